// Opaque appearance models (albedo a, perceptual roughness r, specular s; alpha = max(r^2, 1e-3),
// GGX distribution D, cosD = wi.h):
// - PrincipledV1 (Blender 2.8-3.x Principled BSDF, Cycles, metallic 0, specular tint 0):
//   f = a Burley(r) + F_dielectric(cosD, eta) D G1(wi) G1(wo) / (4 mu_i mu_o), the exact
//   unpolarised Fresnel with eta = (1 + sqrt(F0)) / (1 - sqrt(F0)), F0 = 0.08 s (Cycles'
//   ior = 2 / (1 - sqrt(0.08 s)) - 1), separable Smith masking, the lobes added.
// - Gltf (glTF 2.0 metallic-roughness BRDF with KHR_materials_specular, metallic 0):
//   f = (1 - F) a / pi + F D G2(wi, wo) / (4 mu_i mu_o), Schlick F = 0.08 s + (s - 0.08 s)(1 - cosD)^5
//   (F0 = 0.08 s, F90 = s), height-correlated Smith G2: the spec's fresnel_mix of Lambert and GGX.
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
  BsdfModel model = BsdfModel::PrincipledV1;
};

inline constexpr float kAlphaMin = 1e-3f;
inline float ggxAlpha(float r) { return std::max(r * r, kAlphaMin); }

// What evalBsdf computes; value, pdf and derivatives share the half-vector and GGX terms.
enum BsdfQuery : unsigned { kBsdfValue = 1, kBsdfPdf = 2, kBsdfDerivatives = 4 };

// f, the sampling pdf of wi, and derivatives of f w.r.t. the parameters, from one evaluation.
struct BsdfEval {
  Color f = Color::Zero();
  float pdf = 0;                     // solid angle, of the whole sampling mixture
  float dAlbedo = 0;                 // df_c / d albedo_c (same for every channel)
  Color dRoughness = Color::Zero();  // includes the Burley diffuse's roughness coupling
  Color dSpecular = Color::Zero();   // includes glTF's diffuse weight 1 - F
};

// The model's Fresnel factor F(cosD) of the specular lobe (specular s included) and dF/ds.
struct Fresnel {
  float value = 0, dSpecular = 0;
};
Fresnel specularFresnel(BsdfModel model, float cosD, float specular);

// Double-precision evaluation of the same value and derivatives (tests check the analytic
// derivatives against finite differences of this).
struct BsdfEvalDouble {
  template <typename T>
  struct Of {
    Eigen::Array<T, 3, 1> f = Eigen::Array<T, 3, 1>::Zero(), dRoughness = Eigen::Array<T, 3, 1>::Zero(),
                          dSpecular = Eigen::Array<T, 3, 1>::Zero();
    T dAlbedo = 0;
  };
  Eigen::Array3d f = Eigen::Array3d::Zero(), dRoughness = Eigen::Array3d::Zero(), dSpecular = Eigen::Array3d::Zero();
  double dAlbedo = 0;
  BsdfEvalDouble() = default;
  BsdfEvalDouble(const Of<double>& o) : f(o.f), dRoughness(o.dRoughness), dSpecular(o.dSpecular), dAlbedo(o.dAlbedo) {}
};
BsdfEvalDouble evalBsdfDouble(const Eigen::Array3d& albedo, double roughness, double specular, BsdfModel model,
                              const Eigen::Vector3d& wo, const Eigen::Vector3d& wi);

struct BsdfSample {
  Vec3 wi;
  float pdf = 0;  // solid angle, of the whole mixture
  Color f;
  Color weight;  // f * cos / pdf
};

// Probability of picking the GGX lobe: a detached function of the parameters (the model's Fresnel
// at wo against the diffuse albedo), in [0.1, 0.9].
float specularLobeProbability(const BsdfParams& p, const Vec3& wo);

// The BSDF at one path vertex: parameters and wo fixed. What depends on them alone (GGX alpha,
// Smith Lambda of wo, the lobe probability) is computed once, not in each of the vertex's
// evaluations (next-event estimation, the BSDF sample and its pdf).
class VertexBsdf {
 public:
  VertexBsdf(const BsdfParams& p, const Vec3& wo);
  BsdfEval eval(const Vec3& wi, unsigned query = kBsdfValue) const;
  // uLobe picks the lobe (detached), u2 drives the warp.
  std::optional<BsdfSample> sample(float uLobe, const Vec2& u2) const;

 private:
  BsdfParams p_;
  Vec3 wo_;
  float alpha_, lambdaO_, specularProbability_;
};

BsdfEval evalBsdf(const BsdfParams& p, const Vec3& wo, const Vec3& wi, unsigned query = kBsdfValue);
inline float pdfBsdf(const BsdfParams& p, const Vec3& wo, const Vec3& wi) { return evalBsdf(p, wo, wi, kBsdfPdf).pdf; }
inline std::optional<BsdfSample> sampleBsdf(const BsdfParams& p, const Vec3& wo, float uLobe, const Vec2& u2) {
  return VertexBsdf(p, wo).sample(uLobe, u2);
}

}  // namespace relume
