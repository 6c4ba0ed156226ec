#include "optim/gauss_newton.h"

#include <algorithm>
#include <cmath>

namespace relume {

size_t GaussNewtonState::step(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo,
                              float hi, const GaussNewtonSettings& s) {
  size_t updated = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    if (g[i] == 0.0f && h[i] == 0.0f) continue;
    if (!std::isfinite(g[i]) || !std::isfinite(h[i]) || h[i] < 0.0f) continue;
    curvature[i] = s.beta * curvature[i] + (1.0f - s.beta) * h[i];
    if (steps[i] < 65535) ++steps[i];
    const float average = curvature[i] / (1.0f - std::pow(s.beta, static_cast<float>(steps[i])));
    if (!(average > 0.0f)) continue;  // no sensitivity seen yet (a gradient from a deeper vertex only)
    // 1/n: the first visits average their Newton targets exactly (the target hardly moves while
    // the lights are fixed), later ones keep an exponential average over ~1/damping visits.
    const float damping = std::max(s.damping, 1.0f / static_cast<float>(steps[i]));
    const float delta = std::clamp(damping * g[i] / average, -s.maxStep, s.maxStep);
    x[i] = std::clamp(x[i] - delta, lo, hi);
    ++updated;
  }
  return updated;
}

}  // namespace relume
