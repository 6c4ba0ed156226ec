// Process-level utilities: thread pool control, FTZ/DAZ, timers, peak memory, progress.
#pragma once
#include <tbb/global_control.h>

#include <atomic>
#include <mutex>
#include <chrono>
#include <cstddef>
#include <memory>
#include <string>

namespace relume {

// Sets FTZ/DAZ on the calling thread and limits TBB (and Embree, which shares TBB) to `threads`
// (0 = all cores). Keep the returned object alive for the run.
std::unique_ptr<tbb::global_control> initThreads(int threads);
int threadCount();

double peakRssMiB();  // VmHWM of this process
// User + system CPU seconds of this process, all threads: a cost that other processes sharing
// the cores do not inflate (wall time does).
double processCpuSeconds();

class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

// Thread-safe progress bar on stderr with ETA; silent when stderr is not a terminal unless forced.
class Progress {
 public:
  Progress(std::string label, size_t total);
  ~Progress();
  void advance(size_t n = 1);
  void note(std::string text);  // shown after the bar (e.g. loss, rays/s)

 private:
  void draw(bool final);
  std::string label_, note_;
  std::mutex noteMutex_;
  size_t total_;
  std::atomic<size_t> done_{0};
  std::atomic<long> lastDrawMs_{-1000};
  Timer timer_;
  bool enabled_;
};

}  // namespace relume
