#include "optim/adam.h"

#include <algorithm>
#include <cmath>

namespace relume {

size_t AdamState::step(std::span<float> x, std::span<const float> g, float lo, float hi, const AdamSettings& s,
                       uint32_t globalStep) {
  size_t updated = 0;
  const float b1 = s.beta1, b2 = s.beta2;
  const float globalC1 = 1.0f - std::pow(b1, static_cast<float>(globalStep));
  const float globalC2 = 1.0f - std::pow(b2, static_cast<float>(globalStep));
  for (size_t i = 0; i < x.size(); ++i) {
    // A NaN or Inf entry carries no information (clampGradients drops them, but it can be off):
    // once in m and v it would freeze the entry for good.
    const float gi = std::isfinite(g[i]) ? g[i] : 0.0f;
    if (s.masked && gi == 0.0f) continue;
    m[i] = b1 * m[i] + (1.0f - b1) * gi;
    v[i] = b2 * v[i] + (1.0f - b2) * gi * gi;
    float c1 = globalC1, c2 = globalC2;
    if (s.perEntrySteps) {
      if (steps[i] < 65535) ++steps[i];
      c1 = 1.0f - std::pow(b1, static_cast<float>(steps[i]));
      c2 = 1.0f - std::pow(b2, static_cast<float>(steps[i]));
    }
    const float lr =
        s.relativeFloor > 0.0f ? s.learningRate * std::max(std::abs(x[i]), s.relativeFloor) : s.learningRate;
    const float delta = lr * (m[i] / c1) / (std::sqrt(v[i] / c2) + s.epsilon);
    if (std::isfinite(delta)) x[i] = std::clamp(x[i] - delta, lo, hi);
    ++updated;
  }
  return updated;
}

float clampGradients(std::span<float> g, float factor) {
  if (factor <= 0.0f) return 0.0f;
  std::vector<float> mags;
  for (float v : g)
    if (v != 0.0f && std::isfinite(v)) mags.push_back(std::abs(v));
  if (mags.empty()) return 0.0f;
  auto mid = mags.begin() + mags.size() / 2;
  std::nth_element(mags.begin(), mid, mags.end());
  const float bound = factor * *mid;
  for (float& v : g) v = std::isfinite(v) ? std::clamp(v, -bound, bound) : 0.0f;
  return bound;
}

void PolyakAverage::add(std::span<const float> x) {
  if (mean.size() != x.size()) mean.assign(x.begin(), x.end()), count = 0;
  ++count;
  const float w = 1.0f / static_cast<float>(count);
  for (size_t i = 0; i < x.size(); ++i) mean[i] += (x[i] - mean[i]) * w;
}

}  // namespace relume
