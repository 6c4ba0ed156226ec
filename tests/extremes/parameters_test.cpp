// Parameters at the edges of their domains, and emitters across ten decades of radiance.
#include "extremes.h"

using namespace relume;
using namespace relume::extremes;

namespace {

const std::vector<ParamKind> kMaterialKinds = {ParamKind::Albedo, ParamKind::Roughness, ParamKind::Specular};

void setAll(std::vector<float>& values, float v) { std::fill(values.begin(), values.end(), v); }

// The furnace: a closed sphere whose inside emits E and reflects with albedo a (the one
// object), glTF with specular 0, i.e. exactly Lambertian. Rays from cameras inside it.
struct Furnace {
  GradientExperiment e;
  Scene scene;
  explicit Furnace(int rays = 1024)
      : e(makeGradientExperiment(makeSynthScene(SynthSceneKind::Furnace, 16).scene,
                                 synthCameraPath(SynthSceneKind::Furnace, 4, 32, 24, 0.0), options(rays))),
        scene(e.truth.mesh) {}
  static ExperimentOptions options(int rays) {
    ExperimentOptions o;
    o.rays = rays;
    o.referenceSpp = 1;
    o.maxDepth = kDepth;
    return o;
  }
  Appearance lambertian(float albedo, float emission) const {
    Appearance a = e.truth.appearance;
    a.model = BsdfModel::Gltf;
    setAll(a.specular, 0.0f);
    setAll(a.albedo.rgb, albedo);
    for (Color& c : a.albedoConstant) c = Color::Constant(albedo);
    for (Color& c : a.emission) c = Color::Constant(emission);
    return a;
  }
  static constexpr int kDepth = 4;
};

}  // namespace

TEST(ExtremeParameters, RoughnessAtItsLowerBoundAndAtOne) {
  for (float r : {kRoughnessMin, 1.0f}) {
    GradientExperiment e = cornell();
    setAll(e.current.roughness, r);
    // Bound: the central difference (both sides stay where alpha = r^2 > 1e-3 is smooth) within
    // 2e-3: the GGX derivative must not blow up as the lobe narrows to a near-mirror.
    expectFiniteAndRight(e, kMaterialKinds, "roughness " + std::to_string(r));
  }
}

TEST(ExtremeParameters, SpecularZeroAndOne) {
  for (BsdfModel model : {BsdfModel::PrincipledV1, BsdfModel::Gltf}) {
    GradientExperiment e = cornell();
    e.current.model = model;
    setAll(e.current.specular, 1.0f);
    expectFiniteAndRight(e, kMaterialKinds, std::string("specular 1, ") + bsdfModelName(model));
  }
  // At s = 0 glTF's Fresnel is linear in s, so a central difference across 0 is exact.
  GradientExperiment e = cornell();
  e.current.model = BsdfModel::Gltf;
  setAll(e.current.specular, 0.0f);
  expectFiniteAndRight(e, kMaterialKinds, "specular 0, gltf");
  // Principled's ior needs sqrt(0.08 s), undefined below 0, so no central difference there. Its
  // F has a term in s^(3/2) (eta - 1 ~ sqrt(s)), so the gradient at s must tend to the one at 0
  // as sqrt(s). Bound: within 20 sqrt(s) relative (measured up to 15 sqrt(s), on the green wall)
  // at s = 1e-6, 1e-8, 1e-10: a wrong or infinite derivative at exactly 0 would not converge.
  e.current.model = BsdfModel::PrincipledV1;
  const Scene scene(e.truth.mesh);
  auto specularGradient = [&](float s) {
    setAll(e.current.specular, s);
    const LightSampler lights(scene, e.current);
    Gradients g(e.current);
    AdjointSettings settings;
    settings.path.maxDepth = 4;
    computeGradients(scene, e.current, lights, e.rays, settings, 0, g);
    EXPECT_TRUE(allFinite(g)) << "principled specular " << s;
    return std::vector<float>(g.objects.begin() + g.specularSlot(0),
                              g.objects.begin() + g.specularSlot(0) + e.current.objectCount());
  };
  const std::vector<float> at0 = specularGradient(0.0f);
  for (float s : {1e-6f, 1e-8f, 1e-10f}) {
    const std::vector<float> atS = specularGradient(s);
    for (size_t o = 0; o < at0.size(); ++o)
      EXPECT_NEAR(atS[o], at0[o], 20 * std::sqrt(s) * std::abs(at0[o])) << "object " << o << ", s = " << s;
  }
  double norm = 0;
  for (float g : at0) norm += std::abs(g);
  EXPECT_GT(norm, 0.0);  // some object reflects the light: the comparison is not 0 == 0
}

TEST(ExtremeParameters, AlbedoZeroAndOne) {
  for (float a : {0.0f, 1.0f}) {
    GradientExperiment e = cornell();
    setAll(e.current.albedo.rgb, a);
    // Bound: the albedo enters linearly, so a difference across 0 or 1 is exact up to rounding.
    expectFiniteAndRight(e, kMaterialKinds, "albedo " + std::to_string(a));
  }
}

TEST(ExtremeParameters, AlbedoZeroReflectsNothingAndAlbedoOneAddsOneEmissionPerVertex) {
  const Furnace f;
  // Albedo 0, specular 0: the BSDF is exactly 0, so each estimate is the emission the camera ray
  // sees, E = 1, to the last bit.
  for (const Color& c : estimates(f.scene, f.lambertian(0.0f, 1.0f), f.e.rays, Furnace::kDepth))
    ASSERT_EQ(c.matrix(), Color::Ones().matrix());
  // Albedo 1: every vertex sees E and reflects all of it, so each of the depth + 1 emission terms
  // (seen directly, then from each vertex) adds E: the mean is 5 E, within 4 standard errors.
  const std::vector<Color> white = estimates(f.scene, f.lambertian(1.0f, 1.0f), f.e.rays, Furnace::kDepth);
  ASSERT_TRUE(allFinite(white));
  double sum = 0, sq = 0;
  for (const Color& c : white) sum += c[0], sq += c[0] * c[0];
  const double n = white.size(), mean = sum / n, se = std::sqrt((sq / n - mean * mean) / n);
  EXPECT_NEAR(mean, Furnace::kDepth + 1.0, 4 * se + 1e-3) << "standard error " << se;
}

TEST(ExtremeParameters, EmittersAtTinyAndHugeRadiance) {
  // Radiance is linear in the emission and light selection is by relative power, so with the same
  // seeds each estimate at E is E times the estimate at 1. Bound: 1e-5 relative (float rounding
  // of a few dozen products), at 1e-4 and at 1e6.
  const Furnace f(256);
  const std::vector<Color> unit = estimates(f.scene, f.lambertian(0.5f, 1.0f), f.e.rays, Furnace::kDepth);
  for (float scale : {1e-4f, 1e6f}) {
    const std::vector<Color> scaled = estimates(f.scene, f.lambertian(0.5f, scale), f.e.rays, Furnace::kDepth);
    for (size_t j = 0; j < unit.size(); ++j)
      ASSERT_NEAR(scaled[j][0] / scale, unit[j][0], 1e-5 * unit[j][0]) << "scale " << scale << " ray " << j;
  }
  // Gradients of a scene with such emitters: finite, and right to gradcheck's tolerance (the
  // emission step scales with the brightest emitter, so rounding of 1e6 radiances stays below it).
  for (float scale : {1e-4f, 1e6f})
    expectFiniteAndRight(cornell(scale), {ParamKind::Emission, ParamKind::Albedo, ParamKind::Roughness},
                         "emission x " + std::to_string(scale));
}
