// Damped diagonal Gauss-Newton step, for unknowns the loss is nearly linear in: each pixel is
// linear in the albedo at its first vertex, so the residual divided by that sensitivity is how
// far the albedo is off. The step is damping x g / h, h a running average (per-entry bias
// correction) of the row-sum curvature the adjoint pass accumulates; entries with no gradient
// this iteration are left alone, as in masked Adam. Adam's step is about lr whatever the residual,
// so a texel 0.3 too dark needs ~0.3 / lr visits at full signal and many more at the 1-spp noise
// level; this step is the residual's own size.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

namespace relume {

struct GaussNewtonSettings {
  float damping = 0.1f;  // fraction of the Newton step taken after the first 1/damping visits
                         // (before: 1/visit, a plain average of the noisy per-visit targets)
  float beta = 0.9f;     // running average of the curvature over an entry's visits
  float maxStep = 0.25f; // bound on |step| per iteration, in value units (guards rare huge residuals)
};

class GaussNewtonState {
 public:
  GaussNewtonState() = default;
  explicit GaussNewtonState(size_t entries) : curvature(entries, 0.0f), steps(entries, 0) {}
  size_t size() const { return curvature.size(); }
  // One step on x with gradient g and curvature sample h, then projection onto [lo, hi].
  // Returns the entries updated.
  size_t step(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo, float hi,
              const GaussNewtonSettings& s);

  std::vector<float> curvature;  // running average, not bias-corrected
  std::vector<uint16_t> steps;   // visits, saturating
};

}  // namespace relume
