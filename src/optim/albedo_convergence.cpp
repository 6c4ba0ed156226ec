#include "optim/albedo_convergence.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/check.h"
#include "core/math.h"

namespace relume {
namespace {
// A movement of more than 5 standard errors counts as 5: an entry seen with next to no
// sensitivity would otherwise outweigh all the others.
constexpr double kMostStandardErrors = 5;
}  // namespace

AlbedoConvergence::AlbedoConvergence(std::vector<std::pair<uint32_t, uint32_t>> pairs) : pairs_(std::move(pairs)) {}

AlbedoMovement AlbedoConvergence::check(const GaussNewtonState& state, float bound) {
  CHECK(state.tracksSpread());
  AlbedoMovement m;
  const bool compare = !last_.empty();
  if (!compare) last_.assign(2 * pairs_.size(), std::numeric_limits<float>::quiet_NaN());
  CHECK(last_.size() == 2 * pairs_.size());
  std::vector<float> movement, errors;
  double square = 0, product = 0;
  for (size_t k = 0; k < pairs_.size(); ++k) {
    const uint32_t entry[2] = {pairs_[k].first, pairs_[k].second};
    double d[2];
    bool known = compare;
    for (int s = 0; s < 2; ++s) {
      const uint32_t i = entry[s];
      CHECK(i < state.size());
      const float x = state.unbounded(i), se = state.standardError(i, bound);
      if (se >= 0) errors.push_back(se);
      const float before = last_[2 * k + s];
      known = known && std::isfinite(x) && std::isfinite(before) && se > 0;
      if (known) {
        movement.push_back(std::abs(x - before));
        d[s] = std::clamp((double(x) - before) / se, -kMostStandardErrors, kMostStandardErrors);
      }
      last_[2 * k + s] = x;
    }
    if (known) {
      square += 0.5 * (d[0] * d[0] + d[1] * d[1]);
      product += d[0] * d[1];
      ++m.pairs;
    }
  }
  if (m.pairs > 0 && square > 0) {
    const double noise = std::max(square - product, 1e-6 * square);
    m.ratio = square / noise;
    m.movement = medianOf(std::move(movement));
  }
  if (!errors.empty()) m.standardError = medianOf(std::move(errors));
  return m;
}

}  // namespace relume
