#include "render/bsdf.h"

#include "core/warp.h"

namespace relume {
namespace {

constexpr float kMinCos = 1e-6f;

template <typename T>
T pow5(T x) {
  return (x * x) * (x * x) * x;
}

// GGX terms, templated so the same code runs in double for the derivative tests.
template <typename T>
struct GgxT {
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

// Smallest cosD the exact Fresnel sees: at cosD = 0 and s = 0 it is 0/0, and its s-derivative at
// s = 0 grows as 0.08 / cosD^4 (F ~ 0.04 s (1 + B^2) / cosD^4 until 0.32 s ~ cosD^2), which this
// bound keeps below 1e11. Half vectors that far from the normal (89.94 degrees) have no weight.
constexpr float kMinCosD = 1e-3f;

// The model's Fresnel factor and dF/ds.
// PrincipledV1: exact unpolarised dielectric Fresnel, F = A^2 (1 + B^2) / 2 with g = sqrt(eta^2 - 1 + c^2),
// A = (g - c) / (g + c), B = (c (g + c) - 1) / (c (g - c) + 1) (Cycles' fresnel_dielectric_cos), and
// eta = (1 + q) / (1 - q), q = sqrt(F0), F0 = 0.08 s. With x = eta^2 - 1 = 4q / (1 - q)^2,
// A = x / (g + c)^2 has no cancellation, and dF/dF0 = (dF/dx) (dx/dF0) is formed as
// [dF/dx / x] [x dx/dF0] with x dx/dF0 = 8 (1 + q) / (1 - q)^5: finite at s = 0, where F ~ F0.
// Gltf: Schlick with F0 = 0.08 s and F90 = s. dF/ds is 0 unless `derivative`.
template <typename T>
std::pair<T, T> fresnelT(BsdfModel model, T cosD, T specular, bool derivative) {
  if (model == BsdfModel::Gltf) {
    const T w = pow5(T(1) - std::clamp(cosD, T(0), T(1)));
    return {specular * (T(0.08) + T(0.92) * w), T(0.08) + T(0.92) * w};
  }
  const T c = std::clamp(cosD, T(kMinCosD), T(1));
  const T q = std::sqrt(T(0.08) * specular), oneMinusQ = T(1) - q;
  const T x = T(4) * q / (oneMinusQ * oneMinusQ);
  const T g = std::sqrt(x + c * c), gc = g + c;
  const T a = T(1) / (gc * gc);
  const T A = x * a;
  const T bd = c * (g - c) + T(1);
  const T B = (c * gc - T(1)) / bd;
  const T F = T(0.5) * A * A * (T(1) + B * B);
  if (!derivative) return {F, T(0)};
  const T dAdx = a - A / (g * gc);
  const T dBdx = c * (T(1) - c * c) / (bd * bd * g);
  const T dFdxOverX = a * dAdx * (T(1) + B * B) + A * a * B * dBdx;
  const T xdxdF0 = T(8) * (T(1) + q) / pow5(oneMinusQ);
  return {F, T(0.08) * dFdxOverX * xdxdF0};
}

// Value of f and its parameter derivatives, shared by the float renderer and the double reference.
template <typename T>
BsdfEvalDouble::Of<T> evalValue(const Eigen::Array<T, 3, 1>& albedo, T roughness, T specular, BsdfModel model,
                                const Eigen::Matrix<T, 3, 1>& wo, const Eigen::Matrix<T, 3, 1>& wi,
                                const Eigen::Matrix<T, 3, 1>& h, const GgxT<T>& g, T D, T lo, bool derivatives) {
  BsdfEvalDouble::Of<T> e;
  const T muO = wo.z(), muI = wi.z();
  const T cosD = std::clamp(T(wi.dot(h)), T(0), T(1));
  const auto [F, dFds] = fresnelT<T>(model, cosD, specular, derivatives);
  // Diffuse factor kd (f_diffuse = albedo kd) and its derivatives.
  T kd, dKdDr = T(0), dKdDs = T(0);
  if (model == BsdfModel::PrincipledV1) {  // Burley 2012
    const T fd90 = T(0.5) + T(2) * roughness * cosD * cosD;
    const T a = pow5(T(1) - muI), b = pow5(T(1) - muO);
    const T gi = T(1) + (fd90 - T(1)) * a, go = T(1) + (fd90 - T(1)) * b;
    kd = T(kInvPi) * gi * go;
    dKdDr = T(kInvPi) * (a * go + b * gi) * T(2) * cosD * cosD;
  } else {  // Lambert weighted by 1 - F (fresnel_mix)
    kd = T(kInvPi) * (T(1) - F);
    dKdDs = -T(kInvPi) * dFds;
  }
  // Specular lobe without its Fresnel factor: separable (Principled v1) or height-correlated (glTF) Smith.
  const T li = g.lambda(muI);
  const bool separable = model == BsdfModel::PrincipledV1;
  const T G = separable ? T(1) / ((T(1) + li) * (T(1) + lo)) : T(1) / (T(1) + li + lo);
  const T denom = T(4) * muI * muO;
  const T specNoF = D * G / denom;
  e.f = albedo * kd + F * specNoF;
  if (derivatives) {
    e.dAlbedo = kd;
    e.dSpecular = albedo * dKdDs + dFds * specNoF;
    T dSpecDr = T(0);
    if (roughness * roughness > T(kAlphaMin)) {  // the alpha clamp has zero derivative
      const T dli = g.dLambda(muI), dlo = g.dLambda(wo.z());
      const T dG = separable ? -G * (dli / (T(1) + li) + dlo / (T(1) + lo)) : -G * G * (dli + dlo);
      dSpecDr = F * (g.dD(h) * G + D * dG) / denom * (T(2) * roughness);
    }
    e.dRoughness = albedo * dKdDr + dSpecDr;
  }
  return e;
}

}  // namespace

Fresnel specularFresnel(BsdfModel model, float cosD, float specular) {
  const auto [value, dSpecular] = fresnelT<float>(model, cosD, specular, true);
  return {value, dSpecular};
}

float specularLobeProbability(const BsdfParams& p, const Vec3& wo) {
  const float fs = fresnelT<float>(p.model, wo.z(), p.specular, false).first;
  const float fd = luminance(p.albedo) * (p.model == BsdfModel::Gltf ? 1.0f - fs : 1.0f);
  const float sum = fs + fd;
  return std::clamp(sum > 0 ? fs / sum : 0.5f, 0.1f, 0.9f);
}

namespace {
// f, pdf and derivatives given what depends on (p, wo) alone; ps is read for pdf queries only.
BsdfEval evaluate(const BsdfParams& p, const Vec3& wo, const Vec3& wi, unsigned query, const Ggx& g, float lo,
                  float ps) {
  BsdfEval e;
  const float muO = wo.z(), muI = wi.z();
  if (muO <= kMinCos || muI <= kMinCos) return e;
  const Vec3 h = (wo + wi).normalized();
  const float D = h.z() > 0.0f ? g.D(h) : 0.0f;
  if (query & kBsdfPdf) {
    // Mixture of the cosine lobe and GGX visible normals: pdf(wi) = G1(wo) D(h) / (4 mu_o).
    e.pdf = (1.0f - ps) * muI * kInvPi + ps * D / ((1.0f + lo) * 4.0f * muO);
  }
  if (!(query & (kBsdfValue | kBsdfDerivatives))) return e;
  const auto v =
      evalValue<float>(p.albedo, p.roughness, p.specular, p.model, wo, wi, h, g, D, lo, query & kBsdfDerivatives);
  e.f = v.f;
  e.dAlbedo = v.dAlbedo;
  e.dRoughness = v.dRoughness;
  e.dSpecular = v.dSpecular;
  if (!isFinite(e.f) || !std::isfinite(e.pdf)) e = BsdfEval{};
  return e;
}
}  // namespace

BsdfEval evalBsdf(const BsdfParams& p, const Vec3& wo, const Vec3& wi, unsigned query) {
  if (wo.z() <= kMinCos) return {};
  const Ggx g{{ggxAlpha(p.roughness)}};
  return evaluate(p, wo, wi, query, g, g.lambda(wo.z()), query & kBsdfPdf ? specularLobeProbability(p, wo) : 0.0f);
}

VertexBsdf::VertexBsdf(const BsdfParams& p, const Vec3& wo)
    : p_(p), wo_(wo), alpha_(ggxAlpha(p.roughness)), lambdaO_(0), specularProbability_(0) {
  if (wo.z() <= kMinCos) return;  // eval and sample return nothing
  lambdaO_ = Ggx{{alpha_}}.lambda(wo.z());
  specularProbability_ = specularLobeProbability(p, wo);
}

BsdfEval VertexBsdf::eval(const Vec3& wi, unsigned query) const {
  return evaluate(p_, wo_, wi, query, Ggx{{alpha_}}, lambdaO_, specularProbability_);
}

BsdfEvalDouble evalBsdfDouble(const Eigen::Array3d& albedo, double roughness, double specular, BsdfModel model,
                              const Eigen::Vector3d& wo, const Eigen::Vector3d& wi) {
  if (wo.z() <= kMinCos || wi.z() <= kMinCos) return {};
  const Eigen::Vector3d h = (wo + wi).normalized();
  const GgxT<double> g{std::max(roughness * roughness, double(kAlphaMin))};
  return evalValue<double>(albedo, roughness, specular, model, wo, wi, h, g, g.D(h), g.lambda(wo.z()), true);
}

std::optional<BsdfSample> VertexBsdf::sample(float uLobe, const Vec2& u2) const {
  if (wo_.z() <= kMinCos) return std::nullopt;
  Vec3 wi;
  if (uLobe < specularProbability_) {
    const Vec3 m = Ggx{{alpha_}}.sampleVisibleNormal(wo_, u2);
    wi = 2.0f * wo_.dot(m) * m - wo_;
  } else {
    wi = squareToCosineHemisphere(u2);
  }
  if (wi.z() <= kMinCos) return std::nullopt;
  const BsdfEval e = eval(wi, kBsdfValue | kBsdfPdf);
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
