#include "optim/gauss_newton.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

namespace relume {

size_t GaussNewtonState::step(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo,
                              float hi, const GaussNewtonSettings& s) {
  // Entries are independent: the cores share the scan of the (mostly untouched) texture.
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, x.size(), 1 << 16), size_t{0},
      [&](const tbb::blocked_range<size_t>& range, size_t updated) {
        for (size_t i = range.begin(); i < range.end(); ++i) {
          if (g[i] == 0.0f && h[i] == 0.0f) continue;
          if (!std::isfinite(g[i]) || !std::isfinite(h[i]) || h[i] < 0.0f) continue;
          if (steps[i] < 65535) ++steps[i];
          const float weight = std::max(s.damping, 1.0f / static_cast<float>(steps[i]));
          numerator[i] += weight * (x[i] * h[i] - g[i] - numerator[i]);
          curvature[i] += weight * (h[i] - curvature[i]);
          if (!(curvature[i] > 0.0f)) continue;  // no sensitivity seen yet (a gradient from a deeper vertex only)
          const float target = numerator[i] / curvature[i];
          x[i] = std::clamp(std::clamp(target, x[i] - s.maxStep, x[i] + s.maxStep), lo, hi);
          ++updated;
        }
        return updated;
      },
      std::plus<size_t>());
}

}  // namespace relume
