// Image loss (paper eq. 1): per-channel squared error in linear space, one-sided where the
// reference is clipped, mean over rays. delta = dLoss/dI_hat is the only per-ray state the
// adjoint pass needs.
#pragma once
#include <limits>

#include "core/math.h"

namespace relume {

struct ClipThresholds {
  float low = 0.0f;                                       // vmin: below, the reference is noise
  float high = std::numeric_limits<float>::infinity();    // vmax: at or above, it is saturated
};

// w = [I_hat >= vmin or I > vmin] * [I_hat <= vmax or I < vmax], per channel: a reference at or
// beyond a threshold is clipped (DESIGN "Loss").
inline Color lossWeight(const Color& estimate, const Color& reference, const ClipThresholds& clip) {
  Color w;
  for (int c = 0; c < 3; ++c) {
    const bool low = estimate[c] >= clip.low || reference[c] > clip.low;
    const bool high = estimate[c] <= clip.high || reference[c] < clip.high;
    w[c] = (low && high) ? 1.0f : 0.0f;
  }
  return w;
}

// What the estimate is compared with: a clipped reference only bounds the true value (>= vmax, or
// <= vmin), so the estimate is pulled to that bound, I' = clamp(I, vmin, vmax): with w, the
// residual is min(I_hat - vmax, 0) where I >= vmax and max(I_hat - vmin, 0) where I <= vmin, as
// DESIGN "Loss" states; continuous in I_hat (against I itself the loss jumped at the bound).
inline Color lossTarget(const Color& reference, const ClipThresholds& clip) {
  return reference.max(clip.low).min(clip.high);
}

// Sum over channels of w (I_hat - I')^2, for one ray.
inline float rayLoss(const Color& estimate, const Color& reference, const ClipThresholds& clip) {
  return (lossWeight(estimate, reference, clip) * (estimate - lossTarget(reference, clip)).square()).sum();
}

// d rayLoss / d estimate, scaled by `scale` (1/N for the mean over N rays).
inline Color rayLossGradient(const Color& estimate, const Color& reference, const ClipThresholds& clip, float scale) {
  return 2.0f * scale * lossWeight(estimate, reference, clip) * (estimate - lossTarget(reference, clip));
}

}  // namespace relume
