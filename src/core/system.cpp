#include "core/system.h"

#include <malloc.h>
#include <sys/resource.h>

#include <fmt/format.h>
#include <pmmintrin.h>
#include <unistd.h>
#include <xmmintrin.h>

#include <atomic>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <thread>

namespace relume {

std::unique_ptr<tbb::global_control> initThreads(int threads) {
  // Workers capture the FP mode of the thread that creates the arena, so set it first.
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
  const int n = threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, n);
}

int threadCount() {
  return static_cast<int>(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

namespace {
// A field of /proc/self/status in kB ("VmHWM:", "VmRSS:"), in MiB; 0 when absent.
double statusMiB(std::string_view field) {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind(field, 0) == 0) return std::stod(line.substr(field.size())) / 1024.0;
  return 0.0;
}
}  // namespace

double peakRssMiB() { return statusMiB("VmHWM:"); }
double currentRssMiB() { return statusMiB("VmRSS:"); }
void releaseFreeHeap() { malloc_trim(0); }

double processCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  auto seconds = [](const timeval& t) { return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec); };
  return seconds(u.ru_utime) + seconds(u.ru_stime);
}

std::optional<double> etaSeconds(double elapsedSeconds, double done, double total) {
  if (done <= 0) return std::nullopt;
  return elapsedSeconds / done * std::max(0.0, total - done);
}

std::string formatDuration(double seconds) {
  const long s = std::lround(std::max(0.0, seconds));
  if (s < 60) return fmt::format("{}s", s);
  if (s < 3600) return fmt::format("{}m{:02d}s", s / 60, s % 60);
  return fmt::format("{}h{:02d}m", s / 3600, s % 3600 / 60);
}

std::optional<double> parseDuration(std::string_view text) {
  double total = 0;
  size_t i = 0;
  int parts = 0;
  while (i < text.size()) {
    size_t j = i;
    while (j < text.size() && (std::isdigit(static_cast<unsigned char>(text[j])) || text[j] == '.')) ++j;
    double value = 0;
    const auto [end, ec] = std::from_chars(text.data() + i, text.data() + j, value);
    if (j == i || ec != std::errc() || end != text.data() + j) return std::nullopt;
    double unit = 1;
    if (j < text.size()) {
      const char u = text[j++];
      unit = u == 'h' ? 3600 : u == 'm' ? 60 : u == 's' ? 1 : 0;
      if (unit == 0) return std::nullopt;
    } else if (parts > 0) {
      return std::nullopt;  // "1h30": the last number needs its unit too
    }
    total += value * unit;
    ++parts;
    i = j;
  }
  if (parts == 0 || !std::isfinite(total)) return std::nullopt;
  return total;
}

std::optional<double> parseByteSize(std::string_view text) {
  size_t j = 0;
  while (j < text.size() && (std::isdigit(static_cast<unsigned char>(text[j])) || text[j] == '.')) ++j;
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + j, value);
  if (j == 0 || ec != std::errc() || end != text.data() + j) return std::nullopt;
  std::string unit;
  for (char c : text.substr(j)) unit += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool binaryMark = unit.ends_with("ib");  // "GiB": then a prefix must come before it
  if (binaryMark) unit.resize(unit.size() - 2);
  else if (unit.ends_with("b")) unit.resize(unit.size() - 1);
  static constexpr std::string_view kPrefixes = "kmgt";
  double scale = 1;
  if (unit.size() == 1 && kPrefixes.find(unit[0]) != std::string_view::npos)
    scale = std::ldexp(1.0, 10 * (1 + static_cast<int>(kPrefixes.find(unit[0]))));
  else if (!unit.empty() || binaryMark)
    return std::nullopt;
  const double bytes = value * scale;
  if (!std::isfinite(bytes) || bytes > std::ldexp(1.0, 62)) return std::nullopt;
  return bytes;
}

std::string formatBytes(double bytes) {
  static constexpr const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  int u = 0;
  while (u < 4 && std::abs(bytes) >= 1024) bytes /= 1024, ++u;
  if (u == 0) return fmt::format("{:.0f} B", bytes);
  return fmt::format("{:.{}f} {}", bytes, bytes < 10 ? 2 : bytes < 100 ? 1 : 0, kUnits[u]);
}

namespace {
thread_local Progress* innermostProgress = nullptr;  // the bar a new bar on this thread nests in
}  // namespace

Progress::Progress(std::string label, size_t total)
    : label_(std::move(label)),
      total_(std::max<size_t>(total, 1)),
      outer_(innermostProgress),
      enabled_(!outer_ && isatty(STDERR_FILENO)) {
  innermostProgress = this;
}

Progress::~Progress() {
  innermostProgress = outer_;
  if (outer_) outer_->inner_ = 0.0;  // the unit it carried is the outer's to count
  if (enabled_) draw(true);
}

void Progress::advance(size_t n) {
  done_ += n;
  refresh();
}

void Progress::setTotal(size_t total) {
  total_ = std::max<size_t>(total, 1);
  refresh();
}

void Progress::note(std::string text) {
  std::lock_guard lock(noteMutex_);
  note_ = std::move(text);
}

double Progress::fraction() const {
  return std::min(1.0, (static_cast<double>(done_) + inner_) / static_cast<double>(total_));
}

void Progress::refresh() {
  if (outer_) {
    outer_->inner_ = fraction();
    outer_->refresh();
    return;
  }
  if (!enabled_) return;
  const long now = static_cast<long>(timer_.seconds() * 1000.0);
  long last = lastDrawMs_.load();
  if (now - last >= 200 && lastDrawMs_.compare_exchange_strong(last, now)) draw(false);
}

void Progress::draw(bool final) {
  static std::mutex m;
  std::lock_guard lock(m);
  std::string note;
  {
    std::lock_guard noteLock(noteMutex_);
    note = note_.empty() ? "" : "  " + note_;
  }
  const double frac = fraction(), elapsed = timer_.seconds();
  const std::optional<double> eta = etaSeconds(elapsed, frac, 1.0);
  const int width = 30, filled = static_cast<int>(frac * width);
  const size_t total = total_;
  const std::string count = fmt::format("{}/{}", std::min<size_t>(done_, total), total);
  std::fprintf(stderr, "\r%-18s [%s%s] %5.1f%% %9s %7s ETA %7s%s\033[K%s", label_.c_str(),
               std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(), 100.0 * frac, count.c_str(),
               formatDuration(elapsed).c_str(), eta ? formatDuration(*eta).c_str() : "--", note.c_str(),
               final ? "\n" : "");
  std::fflush(stderr);
}

}  // namespace relume
