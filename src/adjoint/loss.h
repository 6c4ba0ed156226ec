// Image loss (paper eq. 1, continuous form): per-channel squared residual in linear space, mean
// over rays. Where the reference is clipped the residual is one-sided and continuous in the
// estimate: r = min(I_hat - vmax, 0) for a saturated reference, r = max(I_hat - vmin, 0) for a
// dark one, r = I_hat - I otherwise (an indicator weight would make the loss jump by
// (vmax - I)^2 when a noisy estimate crosses vmax). I_hat is the frame's prediction: the rendered
// radiance times the frame's gain (BatchRay::gain; 1 unless the fit estimates per-frame gains).
#pragma once
#include "sampling/batch.h"

namespace relume {

inline Color lossResidual(const Color& estimate, const BatchRay& ray) {
  const Color predicted = ray.gain * estimate;
  const ClipThresholds& clip = ray.clip;
  Color r;
  for (int c = 0; c < 3; ++c) {
    if (ray.reference[c] >= clip.high)
      r[c] = std::min(predicted[c] - clip.high, 0.0f);
    else if (ray.reference[c] <= clip.low)
      r[c] = std::max(predicted[c] - clip.low, 0.0f);
    else
      r[c] = predicted[c] - ray.reference[c];
  }
  return r;
}

// d residual / d estimate: the gain, or 0 on the flat side of a one-sided residual.
inline Color lossResidualSlope(const Color& estimate, const BatchRay& ray) {
  const Color predicted = ray.gain * estimate;
  const ClipThresholds& clip = ray.clip;
  Color s;
  for (int c = 0; c < 3; ++c) {
    if (ray.reference[c] >= clip.high)
      s[c] = predicted[c] < clip.high ? ray.gain[c] : 0.0f;
    else if (ray.reference[c] <= clip.low)
      s[c] = predicted[c] > clip.low ? ray.gain[c] : 0.0f;
    else
      s[c] = ray.gain[c];
  }
  return s;
}

// Sum over channels of r^2, for one ray.
inline float rayLoss(const Color& estimate, const BatchRay& ray) { return lossResidual(estimate, ray).square().sum(); }

// 2 r scale: the per-ray delta of the primal sample (1/N for the mean over N rays). The adjoint
// sample b multiplies it by its own residual slope, so the gradient is that of E[r(a)] E[r(b)].
inline Color rayLossDelta(const Color& estimate, const BatchRay& ray, float scale) {
  return 2.0f * scale * lossResidual(estimate, ray);
}

// The Gauss-Newton weight of a ray whose sensitivities come from samples a and b (the slopes of
// their residuals): 2 scale slope_a slope_b, i.e. d^2 (scale r^2) / dI_hat^2 with r linearised.
inline Color rayCurvatureWeight(const Color& slopeA, const Color& slopeB, float scale) {
  return 2.0f * scale * slopeA * slopeB;
}

}  // namespace relume
