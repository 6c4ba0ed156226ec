// Sampling warps from the unit square, with their densities.
#pragma once
#include "core/math.h"

namespace relume {

inline Vec2 squareToConcentricDisk(const Vec2& u) {
  const float ox = 2.0f * u.x() - 1.0f, oy = 2.0f * u.y() - 1.0f;
  if (ox == 0.0f && oy == 0.0f) return {0.0f, 0.0f};
  float r, theta;
  if (std::abs(ox) > std::abs(oy)) {
    r = ox;
    theta = 0.25f * kPi * (oy / ox);
  } else {
    r = oy;
    theta = 0.5f * kPi - 0.25f * kPi * (ox / oy);
  }
  return {r * std::cos(theta), r * std::sin(theta)};
}

inline Vec3 squareToCosineHemisphere(const Vec2& u) {
  const Vec2 d = squareToConcentricDisk(u);
  return {d.x(), d.y(), safeSqrt(1.0f - d.squaredNorm())};
}
inline float cosineHemispherePdf(float cosTheta) { return cosTheta > 0.0f ? cosTheta * kInvPi : 0.0f; }

inline Vec3 squareToUniformSphere(const Vec2& u) {
  const float z = 1.0f - 2.0f * u.x();
  const float r = safeSqrt(1.0f - z * z);
  const float phi = 2.0f * kPi * u.y();
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Barycentrics (b1, b2) uniformly distributed over a triangle (Heitz 2019 low-distortion map).
inline Vec2 squareToTriangle(const Vec2& u) {
  float b0, b1;
  if (u.y() > u.x()) {
    b0 = u.x() * 0.5f;
    b1 = u.y() - b0;
  } else {
    b1 = u.y() * 0.5f;
    b0 = u.x() - b1;
  }
  return {b0, b1};
}

inline float powerHeuristic(float a, float b) {
  const float a2 = a * a, b2 = b * b;
  const float w = a2 / (a2 + b2);
  return std::isfinite(w) ? w : 0.0f;
}

}  // namespace relume
