#include "optim/gauss_newton.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace relume {

// Entry i's step; false when it has no gradient or no sensitivity yet (nothing updated).
bool GaussNewtonState::stepEntry(size_t i, std::span<float> x, std::span<const float> g, std::span<const float> h,
                                 float lo, float hi, const GaussNewtonSettings& s) {
  if (g[i] == 0.0f && h[i] == 0.0f) return false;
  if (!std::isfinite(g[i]) || !std::isfinite(h[i]) || h[i] < 0.0f) return false;
  if (steps[i] < 65535) ++steps[i];
  const float weight = std::max(s.damping, 1.0f / static_cast<float>(steps[i]));
  const float visit = x[i] * h[i] - g[i];
  if (tracksSpread()) {
    // The visit's residual about the current value x: (x h - g) - x h = -g.
    const float w = residualSquare[i] < 0.0f ? 1.0f : weight;
    residualSquare[i] += w * (g[i] * g[i] - residualSquare[i]);
    weightSquare[i] = (1.0f - weight) * (1.0f - weight) * weightSquare[i] + weight * weight;
  }
  numerator[i] += weight * (visit - numerator[i]);
  curvature[i] += weight * (h[i] - curvature[i]);
  if (!(curvature[i] > 0.0f)) return false;  // no sensitivity seen yet (a gradient from a deeper vertex only)
  const float target = numerator[i] / curvature[i];
  x[i] = std::clamp(std::clamp(target, x[i] - s.maxStep, x[i] + s.maxStep), lo, hi);
  return true;
}

float GaussNewtonState::standardError(size_t i, float bound) const {
  if (!tracksSpread() || residualSquare[i] < 0.0f || !(curvature[i] > 0.0f)) return -1.0f;
  return std::min(std::sqrt(residualSquare[i] * weightSquare[i]) / curvature[i], bound);
}

float GaussNewtonState::unbounded(size_t i) const {
  return steps[i] > 0 && curvature[i] > 0.0f ? numerator[i] / curvature[i] : std::numeric_limits<float>::quiet_NaN();
}

size_t GaussNewtonState::step(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo,
                              float hi, const GaussNewtonSettings& s) {
  // Entries are independent: the cores share the scan.
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, x.size(), 1 << 16), size_t{0},
      [&](const tbb::blocked_range<size_t>& range, size_t updated) {
        for (size_t i = range.begin(); i < range.end(); ++i) updated += stepEntry(i, x, g, h, lo, hi, s);
        return updated;
      },
      std::plus<size_t>());
}

size_t GaussNewtonState::stepTexels(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo,
                                    float hi, const GaussNewtonSettings& s, std::span<const uint32_t> texels) {
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, texels.size(), 1 << 12), size_t{0},
      [&](const tbb::blocked_range<size_t>& range, size_t updated) {
        for (size_t k = range.begin(); k < range.end(); ++k)
          for (size_t i = 3 * size_t{texels[k]}; i < 3 * size_t{texels[k]} + 3; ++i)
            updated += stepEntry(i, x, g, h, lo, hi, s);
        return updated;
      },
      std::plus<size_t>());
}

}  // namespace relume
