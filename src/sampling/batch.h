// One training ray: a camera ray towards a surface point with the reference radiance the frame
// recorded there. Both samplers (texture space, image space) produce these; the loss and the
// adjoint solver consume them.
#pragma once
#include <limits>

#include "core/math.h"

namespace relume {

struct ClipThresholds {
  float low = 0.0f;                                     // vmin: at or below, the reference is noise
  float high = std::numeric_limits<float>::infinity();  // vmax: at or above, it is saturated
};

struct BatchRay {
  Vec3 origin, dir;
  Color reference;
  ClipThresholds clip;
  float weight = 1.0f;  // optional per-ray Jacobian weight (ablation); 1 = omitted, as in the paper
  // The frame's gain: its pixels are gain x radiance (an unrecorded exposure or white balance the
  // fit estimates; 1 when the exposure is known). The clip thresholds apply to gain x radiance.
  Color gain = Color::Ones();
  // The adjoint pass's direction; zero = `dir`. A ray compared with a whole pixel (a pixel
  // footprint) has one: an independent point of the same pixel. The gradient is then that of
  // (E[I_hat] - I)^2; with one point for both passes it would be that of E[(I_hat - I)^2], which
  // adds the radiance's variance within the pixel and so favours a blurrier material.
  Vec3 adjointDir = Vec3::Zero();
  const Vec3& adjointDirection() const { return adjointDir.isZero() ? dir : adjointDir; }
};

}  // namespace relume
