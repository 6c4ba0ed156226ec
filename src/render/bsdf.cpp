#include "render/bsdf.h"

#include "core/warp.h"

namespace relume {
namespace {

constexpr float kMinCos = 1e-6f;

float pow5(float x) { return (x * x) * (x * x) * x; }

struct Ggx {
  float alpha;
  // D and dD/dalpha of a local half vector. t = sin^2 + alpha^2 cos^2 is formed from the
  // tangential components, not as 1 + (alpha^2 - 1) cos^2: at alpha ~ 1e-3 that cancels
  // catastrophically in float and makes D jitter as alpha changes.
  float D(const Vec3& h) const {
    const float a2 = alpha * alpha, c2 = h.z() * h.z();
    const float t = h.x() * h.x() + h.y() * h.y() + a2 * c2;
    return a2 / (kPi * t * t);
  }
  float dD(const Vec3& h) const {
    const float a2 = alpha * alpha, c2 = h.z() * h.z(), s2 = h.x() * h.x() + h.y() * h.y();
    const float t = s2 + a2 * c2;
    return 2.0f * alpha * (s2 - a2 * c2) / (kPi * t * t * t);
  }
  // Smith Lambda and its alpha derivative; tan^2 from the cosine.
  float lambda(float mu) const {
    const float tan2 = std::max(0.0f, 1.0f - mu * mu) / (mu * mu);
    return 0.5f * (std::sqrt(1.0f + alpha * alpha * tan2) - 1.0f);
  }
  float dLambda(float mu) const {
    const float tan2 = std::max(0.0f, 1.0f - mu * mu) / (mu * mu);
    return 0.5f * alpha * tan2 / std::sqrt(1.0f + alpha * alpha * tan2);
  }
  float G1(float mu) const { return 1.0f / (1.0f + lambda(mu)); }
  // Visible-normal density of wo (Heitz 2018): pdf of wi = G1(wo) D(h) / (4 mu_o).
  Vec3 sampleVisibleNormal(const Vec3& wo, const Vec2& u) const {
    const Vec3 vh = Vec3(alpha * wo.x(), alpha * wo.y(), wo.z()).normalized();
    const float lensq = vh.x() * vh.x() + vh.y() * vh.y();
    const Vec3 t1 = lensq > 0 ? Vec3(-vh.y(), vh.x(), 0) / std::sqrt(lensq) : Vec3(1, 0, 0);
    const Vec3 t2 = vh.cross(t1);
    const float r = std::sqrt(u.x()), phi = 2.0f * kPi * u.y();
    const float p1 = r * std::cos(phi);
    const float s = 0.5f * (1.0f + vh.z());
    const float p2 = (1.0f - s) * safeSqrt(1.0f - p1 * p1) + s * r * std::sin(phi);
    const Vec3 nh = p1 * t1 + p2 * t2 + safeSqrt(1.0f - p1 * p1 - p2 * p2) * vh;
    return Vec3(alpha * nh.x(), alpha * nh.y(), std::max(1e-6f, nh.z())).normalized();
  }
};

}  // namespace

float specularLobeProbability(const BsdfParams& p, const Vec3& wo) {
  const float f0 = 0.08f * p.specular;
  const float fs = f0 + (p.specular - f0) * pow5(1.0f - std::clamp(wo.z(), 0.0f, 1.0f));
  const float fd = luminance(p.albedo);
  const float sum = fs + fd;
  return std::clamp(sum > 0 ? fs / sum : 0.5f, 0.1f, 0.9f);
}

BsdfEval evalBsdf(const BsdfParams& p, const Vec3& wo, const Vec3& wi, unsigned query) {
  BsdfEval e;
  const float muO = wo.z(), muI = wi.z();
  if (muO <= kMinCos || muI <= kMinCos) return e;
  const Vec3 h = (wo + wi).normalized();
  const float cosD = std::clamp(wi.dot(h), 0.0f, 1.0f);
  const Ggx g{ggxAlpha(p.roughness)};
  const float D = h.z() > 0.0f ? g.D(h) : 0.0f;
  const float lo = g.lambda(muO);
  if (query & kBsdfPdf) {
    // Mixture of the cosine lobe and GGX visible normals: pdf(wi) = G1(wo) D(h) / (4 mu_o).
    const float ps = specularLobeProbability(p, wo);
    e.pdf = (1.0f - ps) * muI * kInvPi + ps * D / ((1.0f + lo) * 4.0f * muO);
  }
  if (!(query & (kBsdfValue | kBsdfDerivatives))) return e;

  float diffuseFactor = kInvPi, dDiffuseDr = 0.0f;
  if (p.diffuse == DiffuseModel::Disney) {
    const float fd90 = 0.5f + 2.0f * p.roughness * cosD * cosD;
    const float a = pow5(1.0f - muI), b = pow5(1.0f - muO);
    const float gi = 1.0f + (fd90 - 1.0f) * a, go = 1.0f + (fd90 - 1.0f) * b;
    diffuseFactor = kInvPi * gi * go;
    dDiffuseDr = kInvPi * (a * go + b * gi) * 2.0f * cosD * cosD;
  }
  const float w = pow5(1.0f - cosD);
  const float f0 = 0.08f * p.specular;
  const float F = f0 + (p.specular - f0) * w;
  const float li = g.lambda(muI);
  const float G = 1.0f / (1.0f + li + lo);
  const float denom = 4.0f * muI * muO;
  const float specNoF = D * G / denom;
  e.f = p.albedo * diffuseFactor + Color::Constant(F * specNoF);
  if (query & kBsdfDerivatives) {
    e.dAlbedo = diffuseFactor;
    e.dSpecular = (0.08f + 0.92f * w) * specNoF;
    float dSpecDr = 0.0f;
    if (p.roughness * p.roughness > kAlphaMin) {  // the alpha clamp has zero derivative
      const float dG = -G * G * (g.dLambda(muI) + g.dLambda(muO));
      dSpecDr = F * (g.dD(h) * G + D * dG) / denom * (2.0f * p.roughness);
    }
    e.dRoughness = p.albedo * dDiffuseDr + Color::Constant(dSpecDr);
  }
  if (!isFinite(e.f) || !std::isfinite(e.pdf)) e = BsdfEval{};
  return e;
}

std::optional<BsdfSample> sampleBsdf(const BsdfParams& p, const Vec3& wo, float uLobe, const Vec2& u2) {
  if (wo.z() <= kMinCos) return std::nullopt;
  const float ps = specularLobeProbability(p, wo);
  Vec3 wi;
  if (uLobe < ps) {
    const Vec3 m = Ggx{ggxAlpha(p.roughness)}.sampleVisibleNormal(wo, u2);
    wi = 2.0f * wo.dot(m) * m - wo;
  } else {
    wi = squareToCosineHemisphere(u2);
  }
  if (wi.z() <= kMinCos) return std::nullopt;
  const BsdfEval e = evalBsdf(p, wo, wi, kBsdfValue | kBsdfPdf);
  if (!(e.pdf > 0.0f)) return std::nullopt;
  BsdfSample s;
  s.wi = wi;
  s.pdf = e.pdf;
  s.f = e.f;
  s.weight = s.f * (wi.z() / s.pdf);
  if (!isFinite(s.weight)) return std::nullopt;
  return s;
}

}  // namespace relume
