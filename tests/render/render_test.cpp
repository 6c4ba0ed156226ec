// Whole-renderer checks: white furnace, an analytic direct-lighting case, determinism.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "pipeline/synth.h"
#include "render/film.h"

using namespace relume;

namespace {

Color meanRadiance(const Scene& scene, const Appearance& a, const Vec3& origin, const Vec3& dir, int paths, int maxDepth,
                   double* stdError = nullptr) {
  LightSampler lights(scene, a);
  PathSettings s;
  s.maxDepth = maxDepth;
  const AppearanceScope scope = AppearanceScope::uniform(a);
  Eigen::Array3d sum = Eigen::Array3d::Zero(), sum2 = Eigen::Array3d::Zero();
  for (int i = 0; i < paths; ++i) {
    Pcg32 rng(hashTuple({static_cast<uint64_t>(i), 77}));
    const Eigen::Array3d L = tracePath(scene, lights, scope, s, origin, dir, rng).cast<double>();
    sum += L, sum2 += L * L;
  }
  const Eigen::Array3d mean = sum / paths;
  if (stdError) *stdError = std::sqrt(std::max(0.0, (sum2[0] / paths - mean[0] * mean[0]) / paths));
  return mean.cast<float>();
}

}  // namespace

TEST(Render, WhiteFurnace) {
  // Closed sphere, Lambert albedo a, specular 0, emission Le everywhere: radiance is
  // Le (1 - a^(D+1)) / (1 - a) for max depth D, -> Le / (1 - a). glTF at specular 0 is Lambert.
  SynthScene furnace = makeSynthScene(SynthSceneKind::Furnace, 64);
  Appearance& a = furnace.scene.appearance;
  a.model = BsdfModel::Gltf;
  ASSERT_EQ(a.specular[0], 0.0f);
  Scene scene(furnace.scene.mesh);
  for (float albedo : {0.3f, 0.8f}) {
    std::fill(a.albedo.rgb.begin(), a.albedo.rgb.end(), albedo);
    a.emission[0] = Color::Constant(1.0f);
    for (int depth : {8, 64}) {
      double se = 0;
      const Color L = meanRadiance(scene, a, Vec3(0.1f, 0.2f, -0.1f), Vec3(0.3f, 0.5f, 0.8f).normalized(), 20000, depth, &se);
      const double expected = (1 - std::pow(albedo, depth + 1)) / (1 - albedo);
      EXPECT_NEAR(L[0], expected, 4 * se + 1e-4) << "albedo " << albedo << " depth " << depth;
      if (depth == 64) {
        EXPECT_NEAR(L[0], 1 / (1 - albedo), 4 * se + 1e-4);
      }
    }
  }
}

TEST(Render, FurnaceFailsWithWrongAlbedo) {
  // Guard against a test that cannot fail: the estimate does separate nearby albedos.
  SynthScene furnace = makeSynthScene(SynthSceneKind::Furnace, 64);
  Appearance& a = furnace.scene.appearance;
  a.model = BsdfModel::Gltf;
  Scene scene(furnace.scene.mesh);
  std::fill(a.albedo.rgb.begin(), a.albedo.rgb.end(), 0.52f);
  double se = 0;
  const Color L = meanRadiance(scene, a, Vec3::Zero(), Vec3(0, 0, 1), 20000, 64, &se);
  EXPECT_GT(std::abs(L[0] - 1 / (1 - 0.5)), 8 * se);
}

TEST(Render, SmallEmitterAnalyticIrradiance) {
  // Receiver plane y=0 (Lambert albedo rho: glTF with specular 0); square emitter of half-size h at height d
  // facing down. Radiance leaving the receiver point below the centre with direct lighting only:
  // rho/pi * E, E = 4 pi Le F(h/d, h/d) (corner form factor to a parallel rectangle).
  const float h = 0.1f, d = 1.0f, rho = 0.5f, le = 10.0f;
  MeshData m;
  m.positions = {{-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}, {-h, d, -h}, {h, d, -h}, {h, d, h}, {-h, d, h}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}};  // receiver normal +y, emitter normal -y
  m.faceObject = {0, 0, 1, 1};
  Scene scene(buildMesh(m, "two planes"));
  Appearance a(2);
  a.model = BsdfModel::Gltf;
  a.albedoConstant = {Color::Constant(rho), Color::Constant(0)};
  a.specular = {0, 0};
  a.emission[1] = Color::Constant(le);
  const double X = h / d;
  const double F = 1 / (2 * M_PI) * (2 * X / std::sqrt(1 + X * X) * std::atan(X / std::sqrt(1 + X * X)));
  const double E = 4 * M_PI * le * F;
  const double expected = rho / M_PI * E;
  const Vec3 camera(0.8f, 0.5f, 0.3f);
  double se = 0;
  const Color L = meanRadiance(scene, a, camera, (Vec3::Zero() - camera).normalized(), 200000, 1, &se);
  EXPECT_NEAR(L[0], expected, 0.01 * expected);
  EXPECT_LT(se, 0.003 * expected);
}

TEST(Render, DeterministicAcrossThreadCounts) {
  SynthScene room = makeSynthScene(SynthSceneKind::Cornell, 128);
  Scene scene(room.scene.mesh);
  LightSampler lights(scene, room.scene.appearance);
  const Camera cam = synthCameraPath(SynthSceneKind::Cornell, 1, 48, 40, 0.0)[0];
  RenderOptions ro;
  ro.spp = 4;
  ro.seed = 42;
  ro.path.russianRoulette = true;
  std::vector<float> images[2];
  for (int t : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, t);
    images[t - 1] = renderImage(scene, room.scene.appearance, lights, cam, ro).color.rgb;
  }
  ASSERT_EQ(images[0].size(), images[1].size());
  EXPECT_EQ(0, std::memcmp(images[0].data(), images[1].data(), images[0].size() * sizeof(float)));
  ro.seed = 43;
  const auto other = renderImage(scene, room.scene.appearance, lights, cam, ro).color.rgb;
  EXPECT_NE(0, std::memcmp(images[0].data(), other.data(), other.size() * sizeof(float)));
}
