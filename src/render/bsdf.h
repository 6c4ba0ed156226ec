// Opaque appearance model: Disney (Burley 2012) or Lambert diffuse + GGX specular with
// height-correlated Smith masking and Schlick Fresnel, F = F0 + (s - F0)(1 - wi.h)^5 with
// F0 = 0.08 s (glTF KHR_materials_specular: the specular factor scales F90 too, so s = 0 means no
// specular lobe at all). alpha = max(r^2, 1e-3), r the perceptual roughness.
// All directions are in the local shading frame (z = normal) and point away from the surface.
#pragma once
#include <optional>

#include "core/math.h"
#include "scene/appearance.h"

namespace relume {

struct BsdfParams {
  Color albedo = Color::Constant(0.5f);
  float roughness = 0.5f;
  float specular = 0.5f;
  DiffuseModel diffuse = DiffuseModel::Disney;
};

inline constexpr float kAlphaMin = 1e-3f;
inline float ggxAlpha(float r) { return std::max(r * r, kAlphaMin); }

// What evalBsdf computes; value, pdf and derivatives share the half-vector and GGX terms.
enum BsdfQuery : unsigned { kBsdfValue = 1, kBsdfPdf = 2, kBsdfDerivatives = 4 };

// f, the sampling pdf of wi, and derivatives of f w.r.t. the parameters, from one evaluation.
struct BsdfEval {
  Color f = Color::Zero();
  float pdf = 0;                             // solid angle, of the whole sampling mixture
  float dAlbedo = 0;                         // df_c / d albedo_c (same for every channel)
  Color dRoughness = Color::Zero();          // includes the Disney diffuse's roughness coupling
  float dSpecular = 0;                       // achromatic
};

// Double-precision evaluation of the same value and derivatives (tests check the analytic
// derivatives against finite differences of this).
struct BsdfEvalDouble {
  template <typename T> struct Of {
    Eigen::Array<T, 3, 1> f = Eigen::Array<T, 3, 1>::Zero(), dRoughness = Eigen::Array<T, 3, 1>::Zero();
    T dAlbedo = 0, dSpecular = 0;
  };
  Eigen::Array3d f = Eigen::Array3d::Zero(), dRoughness = Eigen::Array3d::Zero();
  double dAlbedo = 0, dSpecular = 0;
  BsdfEvalDouble() = default;
  BsdfEvalDouble(const Of<double>& o) : f(o.f), dRoughness(o.dRoughness), dAlbedo(o.dAlbedo), dSpecular(o.dSpecular) {}
};
BsdfEvalDouble evalBsdfDouble(const Eigen::Array3d& albedo, double roughness, double specular, DiffuseModel diffuse,
                              const Eigen::Vector3d& wo, const Eigen::Vector3d& wi);

struct BsdfSample {
  Vec3 wi;
  float pdf = 0;       // solid angle, of the whole mixture
  Color f;
  Color weight;        // f * cos / pdf
};

BsdfEval evalBsdf(const BsdfParams& p, const Vec3& wo, const Vec3& wi, unsigned query = kBsdfValue);
inline float pdfBsdf(const BsdfParams& p, const Vec3& wo, const Vec3& wi) { return evalBsdf(p, wo, wi, kBsdfPdf).pdf; }
// uLobe picks the lobe (detached), u2 drives the warp.
std::optional<BsdfSample> sampleBsdf(const BsdfParams& p, const Vec3& wo, float uLobe, const Vec2& u2);
// Probability of picking the GGX lobe: a detached function of the parameters, in [0.1, 0.9].
float specularLobeProbability(const BsdfParams& p, const Vec3& wo);

}  // namespace relume
