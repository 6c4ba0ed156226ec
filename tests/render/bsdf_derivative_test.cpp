// Analytic BSDF derivatives against double-precision finite differences of the BSDF itself, for
// every model and parameter, including specular 0 and 1 and grazing directions.
#include <gtest/gtest.h>

#include "core/rng.h"
#include "core/warp.h"
#include "render/bsdf.h"
#include "bsdf_reference.h"

using namespace relume;

namespace {

const BsdfModel kModels[] = {BsdfModel::PrincipledV1, BsdfModel::Gltf};

Eigen::Vector3d randomDir(Pcg32& rng, bool grazing) {
  const double cosTheta = grazing ? 1e-4 + 0.02 * rng.next1D() : 0.02 + 0.98 * rng.next1D();
  const double phi = 2 * M_PI * rng.next1D();
  const double s = std::sqrt(1 - cosTheta * cosTheta);
  return {s * std::cos(phi), s * std::sin(phi), cosTheta};
}

void expectClose(double analytic, double fd, double scale, const std::string& what) {
  // Truncation ~h^2 f''' and rounding ~1e-16/h, both far below 1e-6 relative.
  EXPECT_NEAR(analytic, fd, 1e-6 * std::abs(fd) + 1e-9 * scale) << what;
}

// Central difference, h = 1e-6 in double.
template <class F>
Eigen::Array3d centralDifference(const F& value, double x) {
  const double h = 1e-6;
  return (value(x + h) - value(x - h)) / (2 * h);
}

}  // namespace

TEST(BsdfDerivatives, MatchDoubleFiniteDifferences) {
  Pcg32 rng(11);
  int checked = 0;
  for (BsdfModel model : kModels)
    for (double r : {double(kRoughnessMin), 0.1, 0.45, 1.0 - 2e-6})
      for (double s : {0.0, 0.02, 0.5, 1.0})
        for (int i = 0; i < 60; ++i) {
          const Eigen::Vector3d wo = randomDir(rng, i % 5 == 0), wi = randomDir(rng, i % 7 == 0);
          const Eigen::Array3d albedo(0.2 + 0.7 * rng.next1D(), 0.5, 0.9);
          const BsdfEvalDouble e = evalBsdfDouble(albedo, r, s, model, wo, wi);
          const double scale = e.f.abs().maxCoeff() + 1.0;
          const auto atSpecular = [&](double x) { return evalBsdfDouble(albedo, r, x, model, wo, wi).f; };
          const Eigen::Array3d dR =
              centralDifference([&](double x) { return evalBsdfDouble(albedo, x, s, model, wo, wi).f; }, r);
          Eigen::Array3d dS;
          if (model == BsdfModel::PrincipledV1 && s == 0) {
            // s = 0 is the domain's edge and the exact Fresnel's eta = 1 + 2 sqrt(0.08 s) + ... has no
            // value below it: f = diffuse + F(s) lobe, so df/ds(0) = 0.08 (dF/dF0)(0) lobe, the lobe
            // taken from f(1) - f(0) = F(1) lobe with F(1) from Snell's law.
            const double c = wi.dot((wi + wo).normalized());
            const double lobe =
                (atSpecular(1.0) - atSpecular(0.0))[0] / reference::snellFresnel(c, reference::cyclesIor(1.0));
            dS = Eigen::Array3d::Constant(0.08 * reference::fresnelSlopeAtZero(c) * lobe);
          } else {
            dS = centralDifference(atSpecular, s);  // glTF's f is linear in s, also below 0
          }
          const Eigen::Array3d dA = centralDifference(
              [&](double x) {
                Eigen::Array3d a = albedo;
                a[1] = x;
                return evalBsdfDouble(a, r, s, model, wo, wi).f;
              },
              albedo[1]);
          const std::string what = std::string(bsdfModelName(model)) + " r " + std::to_string(r) + " s " +
                                   std::to_string(s) + " muI " + std::to_string(wi.z()) + " muO " +
                                   std::to_string(wo.z());
          for (int c = 0; c < 3; ++c) {
            expectClose(e.dRoughness[c], dR[c], scale / r, "roughness " + what);
            expectClose(e.dSpecular[c], dS[c], scale, "specular " + what);
          }
          expectClose(e.dAlbedo, dA[1], scale, "albedo " + what);
          EXPECT_TRUE(e.f.allFinite() && e.dRoughness.allFinite() && e.dSpecular.allFinite());
          ++checked;
        }
  EXPECT_EQ(checked, 2 * 4 * 4 * 60);
}

TEST(BsdfDerivatives, SpecularDerivativeAtZeroIsPositive) {
  // At s = 0 the specular lobe is 0 in both models but its derivative is not: the fit can move
  // away from s = 0. glTF's diffuse weight 1 - F makes its df/ds smaller than the lobe alone.
  const Eigen::Vector3d wo = Eigen::Vector3d(0.5, 0.1, 0.7).normalized(),
                        wi = Eigen::Vector3d(-0.4, 0.2, 0.8).normalized();
  for (BsdfModel model : kModels) {
    const BsdfEvalDouble at0 = evalBsdfDouble(Eigen::Array3d::Constant(0.5), 0.3, 0.0, model, wo, wi);
    const BsdfEvalDouble black = evalBsdfDouble(Eigen::Array3d::Zero(), 0.3, 0.0, model, wo, wi);
    EXPECT_GT(black.dSpecular[0], 0.0) << bsdfModelName(model);
    if (model == BsdfModel::Gltf)
      EXPECT_LT(at0.dSpecular[0], black.dSpecular[0]);
    else
      EXPECT_EQ(at0.dSpecular[0], black.dSpecular[0]);
  }
}

TEST(BsdfDerivatives, FloatPathMatchesDoubleReference) {
  Pcg32 rng(12);
  for (BsdfModel model : kModels)
    for (int i = 0; i < 2000; ++i) {
      const Eigen::Vector3d wo = randomDir(rng, false), wi = randomDir(rng, false);
      const BsdfParams p{Color(0.3f, 0.6f, 0.8f), kRoughnessMin + (1 - kRoughnessMin) * rng.next1D(), rng.next1D(),
                         model};
      const BsdfEval f = evalBsdf(p, wo.cast<float>(), wi.cast<float>(), kBsdfValue | kBsdfDerivatives);
      const BsdfEvalDouble d = evalBsdfDouble(p.albedo.cast<double>(), p.roughness, p.specular, p.model, wo, wi);
      const double scale = d.f.abs().maxCoeff() + d.dRoughness.abs().maxCoeff() + 1e-3;
      EXPECT_NEAR(f.f[0], d.f[0], 2e-4 * scale);
      EXPECT_NEAR(f.dRoughness[2], d.dRoughness[2], 2e-4 * scale);
      EXPECT_NEAR(f.dSpecular[1], d.dSpecular[1], 2e-4 * scale);
    }
}

TEST(BsdfDerivatives, RoughnessGradientVanishesOnlyInsideTheAlphaClamp) {
  const Eigen::Vector3d wo(0.3, 0.1, 0.95), wi(-0.2, 0.15, 0.97);
  for (BsdfModel model : kModels) {
    const auto at = [&](double r) {
      return evalBsdfDouble(Eigen::Array3d::Zero(), r, 1.0, model, wo.normalized(), wi.normalized());
    };
    EXPECT_EQ(at(0.02).dRoughness[0], 0.0);           // alpha clamped at 1e-3
    EXPECT_NE(at(kRoughnessMin).dRoughness[0], 0.0);  // r_min sits above the clamp
  }
}
