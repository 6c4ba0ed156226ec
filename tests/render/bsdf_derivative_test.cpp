// Analytic BSDF derivatives against double-precision central differences of the BSDF itself.
#include <gtest/gtest.h>

#include "core/rng.h"
#include "core/warp.h"
#include "render/bsdf.h"

using namespace relume;

namespace {

Eigen::Vector3d randomDir(Pcg32& rng, bool grazing) {
  const double cosTheta = grazing ? 1e-4 + 0.02 * rng.next1D() : 0.02 + 0.98 * rng.next1D();
  const double phi = 2 * M_PI * rng.next1D();
  const double s = std::sqrt(1 - cosTheta * cosTheta);
  return {s * std::cos(phi), s * std::sin(phi), cosTheta};
}

void expectClose(double analytic, double fd, double scale, const std::string& what) {
  // h = 1e-6 in double: truncation ~h^2 f''' and rounding ~1e-16/h, both far below 1e-6 relative.
  EXPECT_NEAR(analytic, fd, 1e-6 * std::abs(fd) + 1e-9 * scale) << what;
}

}  // namespace

TEST(BsdfDerivatives, MatchDoubleFiniteDifferences) {
  Pcg32 rng(11);
  const double h = 1e-6;
  int checked = 0;
  for (DiffuseModel diffuse : {DiffuseModel::Disney, DiffuseModel::Lambert})
    for (double r : {double(kRoughnessMin), 0.1, 0.45, 1.0 - 2e-6})
      for (double s : {0.0, 0.5, 1.0})
        for (int i = 0; i < 60; ++i) {
          const Eigen::Vector3d wo = randomDir(rng, i % 5 == 0), wi = randomDir(rng, i % 7 == 0);
          const Eigen::Array3d albedo(0.2 + 0.7 * rng.next1D(), 0.5, 0.9);
          const BsdfEvalDouble e = evalBsdfDouble(albedo, r, s, diffuse, wo, wi);
          const double scale = e.f.abs().maxCoeff() + 1.0;
          const auto fr = [&](double dr) { return evalBsdfDouble(albedo, r + dr, s, diffuse, wo, wi).f; };
          const auto fs = [&](double ds) { return evalBsdfDouble(albedo, r, s + ds, diffuse, wo, wi).f; };
          const Eigen::Array3d dR = (fr(h) - fr(-h)) / (2 * h), dS = (fs(h) - fs(-h)) / (2 * h);
          Eigen::Array3d up = albedo, down = albedo;
          up[1] += h, down[1] -= h;
          const double dA = (evalBsdfDouble(up, r, s, diffuse, wo, wi).f[1] - evalBsdfDouble(down, r, s, diffuse, wo, wi).f[1]) / (2 * h);
          const std::string what = "r " + std::to_string(r) + " s " + std::to_string(s) + " muI " + std::to_string(wi.z()) +
                                   " muO " + std::to_string(wo.z());
          for (int c = 0; c < 3; ++c) {
            expectClose(e.dRoughness[c], dR[c], scale / r, "roughness " + what);
            expectClose(e.dSpecular, dS[c], scale, "specular " + what);
          }
          expectClose(e.dAlbedo, dA, scale, "albedo " + what);
          EXPECT_TRUE(e.f.allFinite() && e.dRoughness.allFinite() && std::isfinite(e.dSpecular));
          ++checked;
        }
  EXPECT_EQ(checked, 2 * 4 * 3 * 60);
}

TEST(BsdfDerivatives, FloatPathMatchesDoubleReference) {
  Pcg32 rng(12);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d wo = randomDir(rng, false), wi = randomDir(rng, false);
    const BsdfParams p{Color(0.3f, 0.6f, 0.8f), kRoughnessMin + (1 - kRoughnessMin) * rng.next1D(), rng.next1D(),
                       DiffuseModel::Disney};
    const BsdfEval f = evalBsdf(p, wo.cast<float>(), wi.cast<float>(), kBsdfValue | kBsdfDerivatives);
    const BsdfEvalDouble d = evalBsdfDouble(p.albedo.cast<double>(), p.roughness, p.specular, p.diffuse, wo, wi);
    const double scale = d.f.abs().maxCoeff() + d.dRoughness.abs().maxCoeff() + 1e-3;
    EXPECT_NEAR(f.f[0], d.f[0], 2e-4 * scale);
    EXPECT_NEAR(f.dRoughness[2], d.dRoughness[2], 2e-4 * scale);
    EXPECT_NEAR(f.dSpecular, d.dSpecular, 2e-4 * scale);
  }
}

TEST(BsdfDerivatives, RoughnessGradientVanishesOnlyInsideTheAlphaClamp) {
  const Eigen::Vector3d wo(0.3, 0.1, 0.95), wi(-0.2, 0.15, 0.97);
  const auto at = [&](double r) { return evalBsdfDouble(Eigen::Array3d::Constant(0.5), r, 1.0, DiffuseModel::Lambert, wo.normalized(), wi.normalized()); };
  EXPECT_EQ(at(0.02).dRoughness[0], 0.0);                    // alpha clamped at 1e-3
  EXPECT_NE(at(kRoughnessMin).dRoughness[0], 0.0);           // r_min sits above the clamp
}
