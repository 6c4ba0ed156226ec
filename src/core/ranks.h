// The processes of a run launched by `mpirun -np N` (docs/design/distributed.md). Every rank runs
// the same program on the same data and holds the same state; a pass over rays is split by chunk
// (chunk c is traced by rank c mod N) and the ranks then exchange what they traced, so that each
// holds every chunk's result and goes on exactly as one process would: results are bit-identical
// at any N. Without MPI at build time, or when not launched by mpirun, there is one rank and every
// call below is free.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

#include "core/check.h"

namespace relume {

class Ranks {
 public:
  // The run's ranks: one until MpiSession has started with a launcher's environment.
  static Ranks& world();

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }
  bool distributed() const { return size_ > 1; }
  int ranksOnThisHost() const { return local_; }
  // Which rank traces the `chunk`-th chunk of a pass (chunks numbered from the pass's first ray).
  int ownerOf(size_t chunk) const { return static_cast<int>(chunk % static_cast<size_t>(size_)); }
  bool ownsChunk(size_t chunk) const { return ownerOf(chunk) == rank_; }

  // Every rank's bytes, in rank order (this rank's own included). Collective: every rank calls it
  // at the same point of the program.
  std::vector<std::vector<uint8_t>> allGather(const std::vector<uint8_t>& mine);
  // The root's value on every rank (a measured time that must not differ between ranks).
  double rootValue(double value);
  // True when every rank has the same `value` (a fingerprint of what each rank read).
  bool agree(uint64_t value);
  // True when `value` is true on every rank.
  bool allTrue(bool value);
  // The root's bytes on every rank (a name only the root chooses, a record only it computed).
  std::string rootString(const std::string& value);
  // The sum of every rank's `value` (counts of what each rank did).
  uint64_t sum(uint64_t value);
  // Ends every rank of the job with this exit code (an error on one rank would otherwise leave the
  // others waiting in their next exchange).
  [[noreturn]] void abort(int code);

  // Items [chunk * chunkItems, ...) of `items` computed by the chunk's rank, copied to every rank.
  // `items` has the same length on every rank.
  template <typename T>
  void shareChunks(std::vector<T>& items, size_t chunkItems);

  // Bytes this rank has put into exchanges since the start (each reaches the N-1 other ranks).
  uint64_t bytesShared() const { return bytesShared_; }
  // Seconds this rank has spent in exchanges, waiting for the slowest rank included; and of them,
  // in the first step of each (every rank's size, which no rank passes before all have arrived):
  // mostly waiting.
  double exchangeSeconds() const { return exchangeSeconds_; }
  double waitSeconds() const { return waitSeconds_; }

 private:
  friend class MpiSession;
  int rank_ = 0, size_ = 1, local_ = 1;
  uint64_t bytesShared_ = 0;
  double exchangeSeconds_ = 0, waitSeconds_ = 0;
};

// Starts MPI when the process was launched by mpirun as one of several and relume was built with
// MPI; ends it when destroyed. Otherwise a single rank.
class MpiSession {
 public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  // Whether this build can run over MPI ranks.
  static bool available();
  // How many processes the launcher that started this one started (1 without a launcher).
  static int launchedRanks();

 private:
  bool started_ = false;
};

template <typename T>
void Ranks::shareChunks(std::vector<T>& items, size_t chunkItems) {
  // Copied as bytes: plain values (Eigen's fixed-size arrays are their floats, though not formally
  // trivially copyable).
  static_assert(std::is_standard_layout_v<T> && std::is_trivially_destructible_v<T>);
  if (!distributed() || items.empty()) return;
  CHECK(chunkItems > 0);
  const size_t chunks = (items.size() + chunkItems - 1) / chunkItems;
  auto span = [&](size_t c, size_t& begin, size_t& end) {
    begin = c * chunkItems, end = std::min(items.size(), begin + chunkItems);
  };
  std::vector<uint8_t> mine;
  for (size_t c = 0; c < chunks; ++c) {
    if (!ownsChunk(c)) continue;
    size_t b, e;
    span(c, b, e);
    const size_t at = mine.size();
    mine.resize(at + (e - b) * sizeof(T));
    std::memcpy(mine.data() + at, items.data() + b, (e - b) * sizeof(T));
  }
  const std::vector<std::vector<uint8_t>> all = allGather(mine);
  for (int r = 0; r < size_; ++r) {
    if (r == rank_) continue;
    size_t at = 0;
    for (size_t c = static_cast<size_t>(r); c < chunks; c += static_cast<size_t>(size_)) {
      size_t b, e;
      span(c, b, e);
      CHECK(at + (e - b) * sizeof(T) <= all[r].size());  // every rank splits the same length the same way
      std::memcpy(static_cast<void*>(items.data() + b), all[r].data() + at, (e - b) * sizeof(T));
      at += (e - b) * sizeof(T);
    }
    CHECK(at == all[r].size());
  }
}

}  // namespace relume
