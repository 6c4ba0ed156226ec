#include "render/bsdf.h"

#include "core/warp.h"

namespace relume {
namespace {

constexpr float kMinCos = 1e-6f;

template <typename T> T pow5(T x) { return (x * x) * (x * x) * x; }

// GGX terms, templated so the same code runs in double for the derivative tests.
template <typename T> struct GgxT {
  T alpha;
  using V = Eigen::Matrix<T, 3, 1>;
  // D and dD/dalpha of a local half vector. t = sin^2 + alpha^2 cos^2 is formed from the
  // tangential components, not as 1 + (alpha^2 - 1) cos^2: at alpha ~ 1e-3 that cancels
  // catastrophically in float and makes D jitter as alpha changes.
  T D(const V& h) const {
    const T a2 = alpha * alpha, c2 = h.z() * h.z();
    const T t = h.x() * h.x() + h.y() * h.y() + a2 * c2;
    return a2 / (T(kPi) * t * t);
  }
  T dD(const V& h) const {
    const T a2 = alpha * alpha, c2 = h.z() * h.z(), s2 = h.x() * h.x() + h.y() * h.y();
    const T t = s2 + a2 * c2;
    return T(2) * alpha * (s2 - a2 * c2) / (T(kPi) * t * t * t);
  }
  // Smith Lambda and its alpha derivative; tan^2 from the cosine.
  T lambda(T mu) const {
    const T tan2 = std::max(T(0), T(1) - mu * mu) / (mu * mu);
    return T(0.5) * (std::sqrt(T(1) + alpha * alpha * tan2) - T(1));
  }
  T dLambda(T mu) const {
    const T tan2 = std::max(T(0), T(1) - mu * mu) / (mu * mu);
    return T(0.5) * alpha * tan2 / std::sqrt(T(1) + alpha * alpha * tan2);
  }
};

struct Ggx : GgxT<float> {
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

// Value of f and its parameter derivatives, shared by the float renderer and the double reference.
template <typename T>
BsdfEvalDouble::Of<T> evalValue(const Eigen::Array<T, 3, 1>& albedo, T roughness, T specular, DiffuseModel diffuse,
                                const Eigen::Matrix<T, 3, 1>& wo, const Eigen::Matrix<T, 3, 1>& wi,
                                const Eigen::Matrix<T, 3, 1>& h, const GgxT<T>& g, T D, T lo, bool derivatives) {
  BsdfEvalDouble::Of<T> e;
  const T muO = wo.z(), muI = wi.z();
  const T cosD = std::clamp(T(wi.dot(h)), T(0), T(1));
  T diffuseFactor = T(kInvPi), dDiffuseDr = T(0);
  if (diffuse == DiffuseModel::Disney) {
    const T fd90 = T(0.5) + T(2) * roughness * cosD * cosD;
    const T a = pow5(T(1) - muI), b = pow5(T(1) - muO);
    const T gi = T(1) + (fd90 - T(1)) * a, go = T(1) + (fd90 - T(1)) * b;
    diffuseFactor = T(kInvPi) * gi * go;
    dDiffuseDr = T(kInvPi) * (a * go + b * gi) * T(2) * cosD * cosD;
  }
  const T w = pow5(T(1) - cosD);
  const T f0 = T(0.08) * specular;
  const T F = f0 + (specular - f0) * w;
  const T li = g.lambda(muI);
  const T G = T(1) / (T(1) + li + lo);
  const T denom = T(4) * muI * muO;
  const T specNoF = D * G / denom;
  e.f = albedo * diffuseFactor + F * specNoF;
  if (derivatives) {
    e.dAlbedo = diffuseFactor;
    e.dSpecular = (T(0.08) + T(0.92) * w) * specNoF;
    T dSpecDr = T(0);
    if (roughness * roughness > T(kAlphaMin)) {  // the alpha clamp has zero derivative
      const T dG = -G * G * (g.dLambda(muI) + g.dLambda(muO));
      dSpecDr = F * (g.dD(h) * G + D * dG) / denom * (T(2) * roughness);
    }
    e.dRoughness = albedo * dDiffuseDr + dSpecDr;
  }
  return e;
}

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
  const Ggx g{{ggxAlpha(p.roughness)}};
  const float D = h.z() > 0.0f ? g.D(h) : 0.0f;
  const float lo = g.lambda(muO);
  if (query & kBsdfPdf) {
    // Mixture of the cosine lobe and GGX visible normals: pdf(wi) = G1(wo) D(h) / (4 mu_o).
    const float ps = specularLobeProbability(p, wo);
    e.pdf = (1.0f - ps) * muI * kInvPi + ps * D / ((1.0f + lo) * 4.0f * muO);
  }
  if (!(query & (kBsdfValue | kBsdfDerivatives))) return e;
  const auto v = evalValue<float>(p.albedo, p.roughness, p.specular, p.diffuse, wo, wi, h, g, D, lo, query & kBsdfDerivatives);
  e.f = v.f;
  e.dAlbedo = v.dAlbedo;
  e.dRoughness = v.dRoughness;
  e.dSpecular = v.dSpecular;
  if (!isFinite(e.f) || !std::isfinite(e.pdf)) e = BsdfEval{};
  return e;
}

BsdfEvalDouble evalBsdfDouble(const Eigen::Array3d& albedo, double roughness, double specular, DiffuseModel diffuse,
                              const Eigen::Vector3d& wo, const Eigen::Vector3d& wi) {
  if (wo.z() <= kMinCos || wi.z() <= kMinCos) return {};
  const Eigen::Vector3d h = (wo + wi).normalized();
  const GgxT<double> g{std::max(roughness * roughness, double(kAlphaMin))};
  return evalValue<double>(albedo, roughness, specular, diffuse, wo, wi, h, g, g.D(h), g.lambda(wo.z()), true);
}

std::optional<BsdfSample> sampleBsdf(const BsdfParams& p, const Vec3& wo, float uLobe, const Vec2& u2) {
  if (wo.z() <= kMinCos) return std::nullopt;
  const float ps = specularLobeProbability(p, wo);
  Vec3 wi;
  if (uLobe < ps) {
    const Vec3 m = Ggx{{ggxAlpha(p.roughness)}}.sampleVisibleNormal(wo, u2);
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
