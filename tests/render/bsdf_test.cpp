// BSDF, both models: sampling matches the pdf (chi-square), pdf mass, reciprocity, energy, and the
// value against each model's published formulas written out independently here.
#include <gtest/gtest.h>

#include <cmath>

#include "core/rng.h"
#include "core/warp.h"
#include "render/bsdf.h"
#include "bsdf_reference.h"

using namespace relume;

namespace {

Vec3 dirFromAngle(float thetaDeg, float phiDeg = 0) {
  const float t = thetaDeg * kPi / 180, p = phiDeg * kPi / 180;
  return {std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)};
}

const BsdfModel kModels[] = {BsdfModel::PrincipledV1, BsdfModel::Gltf};

BsdfParams params(float albedo, float roughness, float specular, BsdfModel m = BsdfModel::PrincipledV1) {
  return {Color::Constant(albedo), roughness, specular, m};
}

// Upper tail of the chi-square distribution (Wilson-Hilferty; accurate for dof >= 10).
double chi2PValue(double chi2, int dof) {
  const double k = dof;
  const double z = (std::cbrt(chi2 / k) - (1 - 2 / (9 * k))) / std::sqrt(2 / (9 * k));
  return 0.5 * std::erfc(z / std::sqrt(2.0));
}

struct Chi2Result {
  double pValue;
  int dof;
};

// Histogram over (cos theta, phi), which has equal solid angle per bin; expected counts integrate
// the pdf on a sub-grid of each bin. Bins expecting < 5 samples are pooled.
Chi2Result chi2Test(const BsdfParams& p, const Vec3& wo, int samples, uint64_t seed) {
  const int nz = 20, nphi = 40;
  std::vector<double> observed(nz * nphi, 0), expected(nz * nphi, 0);
  Pcg32 rng(seed);
  for (int i = 0; i < samples; ++i) {
    const float uL = rng.next1D();
    const Vec2 u = rng.next2D();
    const auto s = sampleBsdf(p, wo, uL, u);
    if (!s) continue;
    const float phi = std::atan2(s->wi.y(), s->wi.x()) + kPi;
    const int iz = std::min(nz - 1, static_cast<int>(s->wi.z() * nz));
    const int ip = std::min(nphi - 1, static_cast<int>(phi / (2 * kPi) * nphi));
    observed[iz * nphi + ip] += 1;
  }
  const int sub = 12;
  for (int iz = 0; iz < nz; ++iz)
    for (int ip = 0; ip < nphi; ++ip) {
      double sum = 0;
      for (int a = 0; a < sub; ++a)
        for (int b = 0; b < sub; ++b) {
          const double z = (iz + (a + 0.5) / sub) / nz;
          const double phi = (ip + (b + 0.5) / sub) / nphi * 2 * M_PI - M_PI;
          const double r = std::sqrt(std::max(0.0, 1 - z * z));
          sum += pdfBsdf(p, wo, Vec3(r * std::cos(phi), r * std::sin(phi), z));
        }
      const double binArea = (1.0 / nz) * (2 * M_PI / nphi);
      expected[iz * nphi + ip] = sum / (sub * sub) * binArea * samples;
    }
  double chi2 = 0, pooledO = 0, pooledE = 0;
  int dof = -1;
  for (size_t i = 0; i < observed.size(); ++i) {
    if (expected[i] < 5) {
      pooledO += observed[i], pooledE += expected[i];
      continue;
    }
    chi2 += (observed[i] - expected[i]) * (observed[i] - expected[i]) / expected[i];
    ++dof;
  }
  if (pooledE >= 5)
    chi2 += (pooledO - pooledE) * (pooledO - pooledE) / pooledE, ++dof;
  else
    EXPECT_LT(pooledO, 20 + 4 * pooledE) << "samples where the pdf says almost none";
  return {chi2PValue(chi2, dof), dof};
}

struct Config {
  float albedo, roughness, specular, thetaDeg;
};
const Config kConfigs[] = {{0.5f, 0.5f, 0.5f, 30}, {0.8f, 0.15f, 1.0f, 10}, {0.2f, 0.3f, 1.0f, 70},
                           {0.5f, 1.0f, 0.5f, 85}, {0.0f, 0.2f, 1.0f, 45},  {0.9f, 0.7f, 0.0f, 60}};

}  // namespace

TEST(Bsdf, SamplingMatchesPdfChiSquare) {
  const int tests = static_cast<int>(std::size(kConfigs));
  const double alpha = 1.0 - std::pow(1.0 - 0.01, 1.0 / (2 * tests));  // Sidak correction
  for (BsdfModel m : kModels)
    for (int i = 0; i < tests; ++i) {
      const Config& c = kConfigs[i];
      const auto r =
          chi2Test(params(c.albedo, c.roughness, c.specular, m), dirFromAngle(c.thetaDeg, 20), 400000, 100 + i);
      EXPECT_GT(r.pValue, alpha) << bsdfModelName(m) << " config " << i << " dof " << r.dof;
      EXPECT_GT(r.dof, 30);
    }
}

TEST(Bsdf, ChiSquareDetectsAWrongPdf) {
  // The test must be able to fail: a pdf that ignores the specular lobe is rejected.
  BsdfParams p = params(0.1f, 0.15f, 1.0f);
  const Vec3 wo = dirFromAngle(30);
  const int nz = 20;
  std::vector<double> obs(nz, 0);
  Pcg32 rng(9);
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const Vec2 u = rng.next2D();
    const auto s = sampleBsdf(p, wo, rng.next1D(), u);
    if (s) obs[std::min(nz - 1, static_cast<int>(s->wi.z() * nz))] += 1;
  }
  double chi2 = 0;
  for (int iz = 0; iz < nz; ++iz) {
    const double z0 = double(iz) / nz, z1 = double(iz + 1) / nz;
    const double e = n * (z1 * z1 - z0 * z0);  // cosine-only hypothesis
    chi2 += (obs[iz] - e) * (obs[iz] - e) / e;
  }
  EXPECT_LT(chi2PValue(chi2, nz - 1), 1e-6);
}

TEST(Bsdf, PdfMassMatchesSamplingSuccess) {
  // The pdf integrates to the probability that sampling succeeds (GGX reflections below the
  // horizon are rejected); the tolerance is 4 standard errors of the uniform-sphere estimate.
  for (BsdfModel m : kModels)
    for (const Config& c : kConfigs) {
      const BsdfParams p = params(c.albedo, c.roughness, c.specular, m);
      const Vec3 wo = dirFromAngle(c.thetaDeg, 10);
      Pcg32 rng(3);
      const int n = 400000;
      double sum = 0, sum2 = 0;
      int success = 0;
      for (int i = 0; i < n; ++i) {
        const Vec3 w = squareToUniformSphere(rng.next2D());
        const double v = pdfBsdf(p, wo, w) * 4 * kPi;
        sum += v, sum2 += v * v;
        const Vec2 u = rng.next2D();
        if (sampleBsdf(p, wo, rng.next1D(), u)) ++success;
      }
      const double integral = sum / n, se = std::sqrt((sum2 / n - integral * integral) / n);
      const double rate = double(success) / n, seRate = std::sqrt(rate * (1 - rate) / n);
      EXPECT_LE(integral, 1.0 + 4 * se);
      EXPECT_NEAR(integral, rate, 4 * std::hypot(se, seRate)) << "roughness " << c.roughness << " theta " << c.thetaDeg;
    }
  // Pure cosine lobe: exactly 1.
  Pcg32 rng(4);
  double integral = 0;
  const int n = 400000;
  for (int i = 0; i < n; ++i) integral += cosineHemispherePdf(squareToUniformSphere(rng.next2D()).z()) * 4 * kPi;
  EXPECT_NEAR(integral / n, 1.0, 0.01);
}

TEST(Bsdf, Reciprocity) {
  Pcg32 rng(5);
  for (int i = 0; i < 2000; ++i) {
    const Vec3 a = squareToCosineHemisphere(rng.next2D());
    const Vec3 b = squareToCosineHemisphere(rng.next2D());
    for (BsdfModel m : kModels) {
      const Vec3 r = rng.next3D();
      const BsdfParams p = params(0.3f + 0.6f * r.x(), 0.05f + 0.95f * r.y(), r.z(), m);
      const Color fab = evalBsdf(p, a, b).f, fba = evalBsdf(p, b, a).f;
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(fab[c], fba[c], 1e-4f * std::max(1.0f, fab[c]));
    }
  }
}

double directionalAlbedo(const BsdfParams& p, const Vec3& wo) {
  Pcg32 rng(6);
  double sum = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const Vec2 u = rng.next2D();
    if (const auto s = sampleBsdf(p, wo, rng.next1D(), u)) sum += s->weight.maxCoeff();
  }
  return sum / n;
}

TEST(Bsdf, DirectionalAlbedoAtMostOne) {
  // The GGX lobe alone (albedo 0, specular 1, so F <= 1) conserves energy in both models at every
  // roughness and angle, and glTF at specular 0 is Lambert, which reflects exactly its albedo.
  // (Principled v1 adds its lobes: the sum exceeds 1 at grazing angles for bright albedo.)
  for (BsdfModel m : kModels)
    for (float r : {kRoughnessMin, 0.2f, 0.5f, 1.0f})
      for (float theta : {0.0f, 45.0f, 75.0f, 89.0f})
        EXPECT_LE(directionalAlbedo(params(0.0f, r, 1.0f, m), dirFromAngle(theta)), 1.0 + 0.01)
            << bsdfModelName(m) << " r " << r << " theta " << theta;
  for (float theta : {0.0f, 60.0f, 89.0f})
    EXPECT_NEAR(directionalAlbedo(params(0.7f, 0.5f, 0.0f, BsdfModel::Gltf), dirFromAngle(theta)), 0.7, 0.005);
}

using namespace relume::reference;

namespace {

// f of `model` (albedo 0.6) against `expected(r, s, wi, wo, h)` over roughness, specular and
// directions up to grazing.
template <class Expected>
void expectClosedForm(BsdfModel model, const Expected& expected) {
  for (float r : {0.1f, 0.5f, 1.0f})
    for (float s : {0.0f, 0.3f, 1.0f})
      for (auto [ti, to] : {std::pair{10.0f, 20.0f}, {60.0f, 30.0f}, {80.0f, 85.0f}, {45.0f, 88.0f}}) {
        const Vec3 wi = dirFromAngle(ti, 0), wo = dirFromAngle(to, 160);
        const double e =
            expected(double(r), double(s), wi.cast<double>(), wo.cast<double>(), (wi + wo).normalized().cast<double>());
        const float f = evalBsdf(params(0.6f, r, s, model), wo, wi).f[0];
        EXPECT_NEAR(f, e, 2e-5 * e) << bsdfModelName(model) << " r " << r << " s " << s << " theta " << ti << "," << to;
      }
}

}  // namespace

TEST(Bsdf, PrincipledV1ClosedForm) {
  // Cycles' Principled diffuse (1 - FL/2)(1 - FV/2) + RR (FL + FV + FL FV (RR - 1)), RR = 2 r (wi.h)^2,
  // F = Schlick weight, plus GGX with G1(wi) G1(wo) and the exact Fresnel at Cycles' ior.
  expectClosedForm(BsdfModel::PrincipledV1, [](double r, double s, const Vec3d& wi, const Vec3d& wo, const Vec3d& h) {
    const double cosD = wi.dot(h), alpha = r * r;
    const double fl = std::pow(1 - wi.z(), 5), fv = std::pow(1 - wo.z(), 5), rr = 2 * r * cosD * cosD;
    const double diffuse = 0.6 / M_PI * ((1 - 0.5 * fl) * (1 - 0.5 * fv) + rr * (fl + fv + fl * fv * (rr - 1)));
    const double g = 1 / ((1 + smithLambda(alpha, wi.z())) * (1 + smithLambda(alpha, wo.z())));
    return diffuse + snellFresnel(cosD, cyclesIor(s)) * ggxD(alpha, h.z()) * g / (4 * wi.z() * wo.z());
  });
}

TEST(Bsdf, GltfClosedForm) {
  // glTF 2.0 + KHR_materials_specular, metallic 0: fresnel_mix(Lambert, GGX) with
  // F = s (F0' + (1 - F0') (1 - V.H)^5), F0' = 0.08, and V = G2 / (4 N.L N.V), height-correlated.
  expectClosedForm(BsdfModel::Gltf, [](double r, double s, const Vec3d& wi, const Vec3d& wo, const Vec3d& h) {
    const double alpha = r * r;
    const double F = s * (0.08 + 0.92 * std::pow(1 - wo.dot(h), 5));
    const double vis = 1 / ((1 + smithLambda(alpha, wi.z()) + smithLambda(alpha, wo.z())) * 4 * wi.z() * wo.z());
    return (1 - F) * 0.6 / M_PI + F * ggxD(alpha, h.z()) * vis;
  });
}

TEST(Bsdf, PrincipledFresnelIsTheExactDielectricOne) {
  // F0 = 0.08 s at normal incidence, 1 at grazing for s > 0, 0 everywhere at s = 0, and the Snell form
  // at Cycles' ior in between; glTF's Schlick instead stops at F90 = s.
  for (float s : {0.05f, 0.5f, 1.0f}) {
    EXPECT_NEAR(specularFresnel(BsdfModel::PrincipledV1, 1.0f, s).value, 0.08f * s, 1e-6f);
    EXPECT_GT(specularFresnel(BsdfModel::PrincipledV1, 2e-3f, s).value, 0.9f);
    EXPECT_NEAR(specularFresnel(BsdfModel::Gltf, 0.0f, s).value, s, 1e-6f);
    for (float c : {0.05f, 0.2f, 0.5f, 0.9f})
      EXPECT_NEAR(specularFresnel(BsdfModel::PrincipledV1, c, s).value, snellFresnel(c, cyclesIor(s)), 1e-6)
          << s << " " << c;
  }
  for (float c : {0.01f, 0.5f, 1.0f}) {
    EXPECT_EQ(specularFresnel(BsdfModel::PrincipledV1, c, 0.0f).value, 0.0f);
    EXPECT_NEAR(specularFresnel(BsdfModel::PrincipledV1, c, 0.0f).dSpecular, 0.08 * fresnelSlopeAtZero(c),
                1e-5 * 0.08 * fresnelSlopeAtZero(c));
    EXPECT_EQ(specularFresnel(BsdfModel::Gltf, c, 0.0f).value, 0.0f);
  }
}

TEST(Bsdf, NoNanAtExtremes) {
  for (BsdfModel m : kModels)
    for (float r : {0.0f, kRoughnessMin, 1.0f})
      for (float s : {0.0f, 1.0f})
        for (float ti : {0.0f, 89.99f, 90.0f})
          for (float to : {0.0f, 89.99f}) {
            const BsdfEval e =
                evalBsdf(params(0.5f, r, s, m), dirFromAngle(to), dirFromAngle(ti, 180), kBsdfValue | kBsdfDerivatives);
            EXPECT_TRUE(isFinite(e.f) && isFinite(e.dRoughness) && isFinite(e.dSpecular));
          }
}

TEST(Bsdf, VertexSetUpEvaluatesAsTheOneShotFunctions) {
  // The path tracer builds a VertexBsdf once per vertex (alpha, Lambda(wo) and the lobe
  // probability cached); the adjoint sweep and the frozen-parameter terms call evalBsdf. Both must
  // give the same bits for every query, and sampleBsdf the same sample.
  Pcg32 rng(11);
  int compared = 0;
  for (BsdfModel m : kModels)
    for (int i = 0; i < 2000; ++i) {
      const BsdfParams p{rng.next3D().array(), std::max(kRoughnessMin, rng.next1D()), rng.next1D(), m};
      const Vec2 anglesO = rng.next2D(), anglesI = rng.next2D();
      const Vec3 wo = dirFromAngle(90 * anglesO.x(), 360 * anglesO.y());
      const Vec3 wi = dirFromAngle(100 * anglesI.x(), 360 * anglesI.y());  // a tenth below the surface
      const VertexBsdf vertex(p, wo);
      for (unsigned q : {unsigned{kBsdfValue}, unsigned{kBsdfPdf}, kBsdfValue | kBsdfPdf | kBsdfDerivatives}) {
        const BsdfEval a = vertex.eval(wi, q), b = evalBsdf(p, wo, wi, q);
        EXPECT_TRUE((a.f == b.f).all() && a.pdf == b.pdf && a.dAlbedo == b.dAlbedo &&
                    (a.dRoughness == b.dRoughness).all() && (a.dSpecular == b.dSpecular).all());
        compared += a.pdf > 0 || (a.f > 0).any();
      }
      const float uLobe = rng.next1D();
      const Vec2 u = rng.next2D();
      const auto s = vertex.sample(uLobe, u);
      if (!s) continue;
      // The sample's value and pdf are the one-shot evaluation's at the sampled direction.
      const BsdfEval e = evalBsdf(p, wo, s->wi, kBsdfValue | kBsdfPdf);
      EXPECT_TRUE((s->f == e.f).all() && s->pdf == e.pdf);
    }
  EXPECT_GT(compared, 2 * 2000);
}
