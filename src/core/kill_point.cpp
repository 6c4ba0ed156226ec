#include "core/kill_point.h"

#include <signal.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <charconv>
#include <cstdlib>
#include <string>

#include <fmt/ranges.h>

#include "core/check.h"
#include "core/error.h"

namespace relume {

namespace {

constexpr std::array<std::string_view, 4> kPoints = {"atomic-write", "checkpoint-half", "result-half",
                                                     "result-staged"};

struct KillAt {
  std::string point;  // empty: no kill asked for
  long pass = 0;
};

KillAt parseKillAt() {
  const char* value = std::getenv("RELUME_KILL_AT");
  if (!value || !*value) return {};
  const std::string_view text(value);
  const size_t colon = text.rfind(':');
  KillAt k;
  if (colon != std::string_view::npos) {
    const char* end = text.data() + text.size();
    const auto [last, ec] = std::from_chars(text.data() + colon + 1, end, k.pass);
    if (ec == std::errc() && last == end && k.pass >= 1) k.point = std::string(text.substr(0, colon));
  }
  if (std::find(kPoints.begin(), kPoints.end(), k.point) == kPoints.end())
    fail("RELUME_KILL_AT: '{}' is not <point>:<pass> with a pass >= 1 and a point among {}", text,
         fmt::join(kPoints, ", "));
  return k;
}

}  // namespace

void killPoint(std::string_view point) {
  static const KillAt killAt = parseKillAt();
  static std::atomic<long> passes{0};
  DCHECK(std::find(kPoints.begin(), kPoints.end(), point) != kPoints.end());
  if (killAt.point != point) return;
  if (passes.fetch_add(1) + 1 == killAt.pass) raise(SIGKILL);
}

}  // namespace relume
