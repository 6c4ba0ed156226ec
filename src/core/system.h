// Process-level utilities: thread pool control, FTZ/DAZ, timers, peak memory, progress.
#pragma once
#include <tbb/global_control.h>

#include <atomic>
#include <mutex>
#include <chrono>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

namespace relume {

// Sets FTZ/DAZ on the calling thread and limits TBB (and Embree, which shares TBB) to `threads`
// (0 = all cores). Keep the returned object alive for the run.
std::unique_ptr<tbb::global_control> initThreads(int threads);
int threadCount();

double peakRssMiB();     // VmHWM of this process
double currentRssMiB();  // VmRSS of this process
// Returns the heap's free pages to the system (glibc's malloc_trim), so that the resident set
// read next is what the process holds, not what it held once.
void releaseFreeHeap();
// User + system CPU seconds of this process, all threads: a cost that other processes sharing
// the cores do not inflate (wall time does).
double processCpuSeconds();

class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(); }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Seconds left at the pace so far: elapsed / done * (total - done). Empty before any progress
// (no pace yet); 0 once done reaches total.
std::optional<double> etaSeconds(double elapsedSeconds, double done, double total);
// "42s", "3m05s", "1h02m": a duration as a person reads it.
std::string formatDuration(double seconds);
// The reverse, in seconds: "600", "90s", "10m", "1.5h", "1h30m" (numbers each followed by h, m or
// s, or one bare number of seconds). Empty for any other text.
std::optional<double> parseDuration(std::string_view text);
// A size in bytes as a person types it: "2G", "1.5GiB", "512M", "512MB", "64k" (K, M, G and T are
// binary: 1024-based, as in `ulimit`, Slurm and Docker; the case and a trailing "B" or "iB" do not
// matter) or a bare number of bytes. Empty for any other text, a negative size or one beyond 2^62.
std::optional<double> parseByteSize(std::string_view text);
// "1.9 GiB", "512 MiB", "20 KiB", "200 B": a size as a person reads it.
std::string formatBytes(double bytes);

// Thread-safe progress bar on stderr: label, bar, units done, elapsed time and ETA; silent when
// stderr is not a terminal. A bar created while another bar created on the same thread is alive
// is nested in it: it draws nothing itself and carries its outer bar through the outer's current
// unit, so a phase bar over frames moves while each frame renders (its own bar nested).
class Progress {
 public:
  Progress(std::string label, size_t total);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  void advance(size_t n = 1);
  void note(std::string text);  // shown after the bar (e.g. loss, rays/s)
  void setTotal(size_t total);  // the work turned out longer or shorter (a replanned fit stage)
  // Fraction done in [0, 1], a nested bar's share of the current unit included.
  double fraction() const;

 private:
  void refresh();  // after a change: this bar's outer bar takes it into account, or this bar draws
  void draw(bool final);
  std::string label_, note_;
  std::mutex noteMutex_;
  std::atomic<size_t> total_;
  std::atomic<size_t> done_{0};
  std::atomic<double> inner_{0.0};  // the nested bar's fraction of the current unit
  std::atomic<long> lastDrawMs_{-1000};
  Timer timer_;
  Progress* outer_;
  bool enabled_;
};

}  // namespace relume
