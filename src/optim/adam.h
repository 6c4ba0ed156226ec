// Adam (Kingma & Ba 2014) over one parameter group, with the paper's two modifications
// (Nimier-David et al. 2021, 3.4): gradients clamped before the update, and the update and both
// moment updates masked to entries whose gradient is nonzero this iteration. Entries keep their
// own step count, so a texel first seen late gets the bias correction of its first step, not of
// the global iteration (with a global count its first step is lr (1 - b1) / sqrt(1 - b2) ~ 3.2 lr).
#pragma once
#include <cstdint>
#include <span>
#include <vector>

namespace relume {

struct AdamSettings {
  float learningRate = 0.01f;
  float beta1 = 0.9f, beta2 = 0.999f, epsilon = 1e-8f;
  bool masked = true;         // update only entries with a nonzero gradient (paper); off: every entry
  bool perEntrySteps = true;  // bias correction from each entry's own step count
  // Step proportional to the value's magnitude, lr * max(|x|, relativeFloor): for unknowns that
  // span decades (emission 1e-3..1e4), where a fixed step is too small for bright emitters and
  // too large for dim ones. 0 = plain additive steps.
  float relativeFloor = 0.0f;
};

class AdamState {
 public:
  AdamState() = default;
  explicit AdamState(size_t entries) : m(entries, 0.0f), v(entries, 0.0f), steps(entries, 0) {}
  size_t size() const { return m.size(); }
  // One step on x with gradient g (already clamped; NaN or Inf entries count as 0), then projection
  // onto [lo, hi].
  // `globalStep` (1-based) is used when per-entry steps are off. Returns the entries updated.
  size_t step(std::span<float> x, std::span<const float> g, float lo, float hi, const AdamSettings& s,
              uint32_t globalStep);

  std::vector<float> m, v;
  std::vector<uint16_t> steps;  // saturates at 65535, where the bias correction is 1 to float precision
};

// Clamps every gradient entry to +-bound, bound = factor x the median magnitude of the nonzero
// entries (outliers from improbable light paths would otherwise inflate v for ~1/(1 - b2) = 1000
// iterations). factor <= 0 disables it. Returns the bound used (0 if none).
float clampGradients(std::span<float> g, float factor);

// Polyak-Ruppert average of the iterates: mean <- mean + (x - mean) / n.
class PolyakAverage {
 public:
  void add(std::span<const float> x);
  bool empty() const { return count == 0; }
  std::vector<float> mean;
  uint32_t count = 0;
};

}  // namespace relume
