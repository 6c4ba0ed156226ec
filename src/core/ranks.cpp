#include "core/ranks.h"

#include "core/system.h"

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <cstring>

#ifdef RELUME_WITH_MPI
#include <mpi.h>
#endif

namespace relume {

Ranks& Ranks::world() {
  static Ranks ranks;
  return ranks;
}

bool MpiSession::available() {
#ifdef RELUME_WITH_MPI
  return true;
#else
  return false;
#endif
}

int MpiSession::launchedRanks() {
  // Open MPI's mpirun; MPICH's (and Slurm's PMI-2); a Slurm job step (srun), whatever its PMI.
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "SLURM_STEP_NUM_TASKS"})
    if (const char* size = std::getenv(v)) return std::max(1, std::atoi(size));
  return 1;
}

#ifdef RELUME_WITH_MPI
namespace {
void checkMpi(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int n = 0;
  MPI_Error_string(rc, text, &n);
  std::fprintf(stderr, "relume: %s failed: %.*s\n", what, n, text);
  MPI_Abort(MPI_COMM_WORLD, 1);
  std::abort();  // MPI_Abort does not return
}
}  // namespace

MpiSession::MpiSession() {
  if (launchedRanks() < 2) return;
  int provided = 0;
  // Only the main thread exchanges; TBB's workers never call MPI.
  checkMpi(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "MPI_Init_thread");
  started_ = true;
  if (provided < MPI_THREAD_FUNNELED) {
    std::fprintf(stderr, "relume: this MPI library cannot run beside threads (MPI_THREAD_FUNNELED)\n");
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  Ranks& w = Ranks::world();
  MPI_Comm_rank(MPI_COMM_WORLD, &w.rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &w.size_);
  MPI_Comm host;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &host);
  MPI_Comm_size(host, &w.local_);
  MPI_Comm_free(&host);
}

MpiSession::~MpiSession() {
  if (started_) MPI_Finalize();
}

std::vector<std::vector<uint8_t>> Ranks::allGather(const std::vector<uint8_t>& mine) {
  if (!distributed()) return {mine};
  const Timer timer;
  bytesShared_ += mine.size();
  std::vector<uint64_t> sizes(static_cast<size_t>(size_));
  const uint64_t own = mine.size();
  checkMpi(MPI_Allgather(&own, 1, MPI_UINT64_T, sizes.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD), "MPI_Allgather");
  waitSeconds_ += timer.seconds();
  // MPI's counts are ints: an exchange of more than 2 GiB in all goes in rounds, each rank sending
  // at most its share of INT_MAX bytes per round (a batch's megabytes take one round).
  const uint64_t piece = static_cast<uint64_t>(INT_MAX) / sizes.size();
  const uint64_t largest = *std::max_element(sizes.begin(), sizes.end());
  std::vector<std::vector<uint8_t>> all(sizes.size());
  for (size_t r = 0; r < sizes.size(); ++r) all[r].reserve(sizes[r]);
  std::vector<int> counts(sizes.size()), offsets(sizes.size());
  std::vector<uint8_t> joined;
  for (uint64_t from = 0; from < largest; from += piece) {
    uint64_t total = 0;
    for (size_t r = 0; r < sizes.size(); ++r) {
      counts[r] = static_cast<int>(sizes[r] > from ? std::min(piece, sizes[r] - from) : 0);
      offsets[r] = static_cast<int>(total);
      total += static_cast<uint64_t>(counts[r]);
    }
    joined.resize(total);
    const int sent = counts[static_cast<size_t>(rank_)];
    checkMpi(MPI_Allgatherv(sent > 0 ? mine.data() + from : mine.data(), sent, MPI_BYTE, joined.data(), counts.data(),
                            offsets.data(), MPI_BYTE, MPI_COMM_WORLD),
             "MPI_Allgatherv");
    for (size_t r = 0; r < sizes.size(); ++r)
      all[r].insert(all[r].end(), joined.begin() + offsets[r], joined.begin() + offsets[r] + counts[r]);
  }
  exchangeSeconds_ += timer.seconds();
  return all;
}

bool Ranks::agree(uint64_t value) {
  if (!distributed()) return true;
  std::vector<uint8_t> mine(sizeof value);
  std::memcpy(mine.data(), &value, sizeof value);
  for (const std::vector<uint8_t>& other : allGather(mine))
    if (other != mine) return false;
  return true;
}

double Ranks::rootValue(double value) {
  if (distributed()) checkMpi(MPI_Bcast(&value, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD), "MPI_Bcast");
  return value;
}

bool Ranks::allTrue(bool value) {
  if (!distributed()) return value;
  int v = value ? 1 : 0, all = 0;
  checkMpi(MPI_Allreduce(&v, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD), "MPI_Allreduce");
  return all == 1;
}

void Ranks::abort(int code) {
  if (distributed()) MPI_Abort(MPI_COMM_WORLD, code);
  std::exit(code);
}

#else

MpiSession::MpiSession() {}
MpiSession::~MpiSession() {}
std::vector<std::vector<uint8_t>> Ranks::allGather(const std::vector<uint8_t>& mine) { return {mine}; }
bool Ranks::agree(uint64_t) { return true; }
double Ranks::rootValue(double value) { return value; }
bool Ranks::allTrue(bool value) { return value; }
void Ranks::abort(int code) { std::exit(code); }

#endif

std::string Ranks::rootString(const std::string& value) {
  if (!distributed()) return value;
  const std::vector<uint8_t> mine = root() ? std::vector<uint8_t>(value.begin(), value.end()) : std::vector<uint8_t>();
  const std::vector<uint8_t> rootBytes = allGather(mine)[0];
  return std::string(rootBytes.begin(), rootBytes.end());
}

uint64_t Ranks::sum(uint64_t value) {
  if (!distributed()) return value;
  std::vector<uint8_t> mine(sizeof value);
  std::memcpy(mine.data(), &value, sizeof value);
  uint64_t total = 0;
  for (const std::vector<uint8_t>& other : allGather(mine)) {
    CHECK(other.size() == sizeof value);
    uint64_t v = 0;
    std::memcpy(&v, other.data(), sizeof v);
    total += v;
  }
  return total;
}

}  // namespace relume
