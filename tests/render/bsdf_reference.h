// Independent double-precision statements of the published formulas the BSDF tests compare with.
#pragma once
#include <cmath>

namespace relume::reference {

inline double ggxD(double alpha, double cosH) {
  const double a2 = alpha * alpha, c2 = cosH * cosH;
  return a2 / (M_PI * std::pow(c2 * (a2 - 1) + 1, 2));
}
inline double smithLambda(double alpha, double mu) {
  return 0.5 * (std::sqrt(1 + alpha * alpha * (1 - mu * mu) / (mu * mu)) - 1);
}
// Unpolarised Fresnel reflectance of a dielectric interface from Snell's law (Born & Wolf).
inline double snellFresnel(double cosI, double eta) {
  const double sinT2 = (1 - cosI * cosI) / (eta * eta), cosT = std::sqrt(1 - sinT2);
  const double rs = (cosI - eta * cosT) / (cosI + eta * cosT), rp = (eta * cosI - cosT) / (eta * cosI + cosT);
  return 0.5 * (rs * rs + rp * rp);
}
// Cycles' Principled v1 ior from the specular input (svm/closure.h).
inline double cyclesIor(double specular) { return 2 / (1 - std::sqrt(0.08 * specular)) - 1; }
// dF/dF0 of the exact Fresnel at F0 = 0 (eta = 1 + 2 sqrt(F0) + ...): the series of Snell's form
// gives F = F0 (1 + (2c^2 - 1)^2) / (2 c^4) + O(F0^1.5).
inline double fresnelSlopeAtZero(double c) { return (1 + std::pow(2 * c * c - 1, 2)) / (2 * std::pow(c, 4)); }

}  // namespace relume::reference
