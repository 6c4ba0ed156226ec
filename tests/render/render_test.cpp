// Whole-renderer checks: white furnace, an analytic direct-lighting case, determinism.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include "core/error.h"
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

namespace {

// Form factor from a differential area to a parallel rectangle with one corner straight above it at
// height 1, sides X and Y (signed: the function is odd in each).
double cornerFormFactor(double X, double Y) {
  const double a = std::sqrt(1 + X * X), b = std::sqrt(1 + Y * Y);
  return 1 / (2 * M_PI) * (X / a * std::atan(Y / a) + Y / b * std::atan(X / b));
}

// Receiver plane y=0 (Lambert albedo rho: glTF with specular 0) around `receiver`; square emitter of
// half-size h, radiance le, at height d above receiver + (dx, 0, dz), facing down. Returns the
// radiance leaving the receiver point towards a camera (direct lighting only) against the analytic
// rho/pi * E, E = pi Le F, F the form factor of the offset rectangle (four signed corner terms).
void expectDirectLightingMatches(const Vec3& receiver, float dx, float dz) {
  const float h = 0.1f, d = 1.0f, rho = 0.5f, le = 10.0f;
  const Vec3 c = receiver + Vec3(dx, d, dz);
  MeshData m;
  m.positions = {receiver + Vec3(-6, 0, -6), receiver + Vec3(6, 0, -6), receiver + Vec3(6, 0, 6), receiver + Vec3(-6, 0, 6),
                 c + Vec3(-h, 0, -h),        c + Vec3(h, 0, -h),        c + Vec3(h, 0, h),        c + Vec3(-h, 0, h)};
  m.triangles = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}};  // receiver normal +y, emitter normal -y
  m.faceObject = {0, 0, 1, 1};
  Scene scene(buildMesh(m, "two planes"));
  Appearance a(2);
  a.model = BsdfModel::Gltf;
  a.albedoConstant = {Color::Constant(rho), Color::Constant(0)};
  a.specular = {0, 0};
  a.emission[1] = Color::Constant(le);
  double F = 0;
  for (int sx : {-1, 1})
    for (int sz : {-1, 1}) F += sx * sz * cornerFormFactor((dx + sx * h) / d, (dz + sz * h) / d);
  const double expected = rho / M_PI * (M_PI * le * F);
  const Vec3 camera = receiver + Vec3(0.8f, 0.5f, 0.3f);
  double se = 0;
  const Color L = meanRadiance(scene, a, camera, (receiver - camera).normalized(), 200000, 1, &se);
  EXPECT_NEAR(L[0], expected, 0.01 * expected) << "emitter offset " << dx << ", " << dz;
  EXPECT_LT(se, 0.003 * expected);
}

}  // namespace

TEST(Render, SmallEmitterAnalyticIrradiance) {
  expectDirectLightingMatches(Vec3::Zero(), 0, 0);
}

TEST(Render, SlantedEmitterIsNotItsOwnOccluder) {
  // The emitter seen 68 degrees from the receiver's normal, 4 m from the origin: shadow rays that
  // left the offset origin along the unoffset direction crossed the emitter's plane before their
  // shortened tmax and were all occluded (only the BSDF-sampled share remained: -99% here).
  expectDirectLightingMatches(Vec3(3, 0, 3), 2.0f, 1.5f);
}

// A pixel straddling an emitter's edge averages the emitter over the camera's pixel filter: with
// the edge 0.6 px right of pixel 4's centre, the unit box sees none of it in pixel 4 and all of it
// in pixel 5; Cycles' Blackman-Harris 1.5 and a Gaussian spread the edge over both.
TEST(Render, PixelsAverageOverTheCamerasFilter) {
  const float edge = 0.6f;
  Camera cam;
  cam.width = 9, cam.height = 3, cam.fx = cam.fy = 9, cam.cx = 4.5f, cam.cy = 1.5f;  // 1 px = 1/9 at z = 1
  MeshData m;  // the emitting half-plane x >= edge of z = 1, facing the camera
  const float x0 = edge / cam.fx;
  m.positions = {Vec3(x0, -5, 1), Vec3(5, -5, 1), Vec3(5, 5, 1), Vec3(x0, 5, 1)};
  m.triangles = {{0, 2, 1}, {0, 3, 2}};
  m.faceObject = {0, 0};
  Scene scene(buildMesh(m, "half plane"));
  ASSERT_LT(scene.mesh().faceNormal(0).z(), 0.0f);
  Appearance a(1);
  a.emission[0] = Color::Constant(1.0f);
  LightSampler lights(scene, a);
  RenderOptions ro;
  ro.spp = 20000;
  ro.path.maxDepth = 0;
  for (const PixelFilter& f : {PixelFilter(), PixelFilter(PixelFilterType::BlackmanHarris, 1.5f), PixelFilter(PixelFilterType::Gaussian, 1.5f)}) {
    cam.filter = f;
    const Image img = renderImage(scene, a, lights, cam, ro).color;
    for (int x = 3; x <= 6; ++x) {
      // The filter's share beyond the edge, seen from pixel x's centre (Simpson's rule on its weight).
      const double from = edge - (x - 4), r = f.radius(), h = 2 * r / 4000;
      double inside = 0, total = 0;
      for (int i = 0; i < 4000; ++i) {
        const double t = -r + i * h;
        const double mass = h / 6 * (f.weight(float(t)) + 4 * f.weight(float(t + h / 2)) + f.weight(float(t + h)));
        total += mass;
        if (t + h / 2 > from) inside += mass;
      }
      for (int y = 0; y < 3; ++y) EXPECT_NEAR(img.at(x, y)[0], inside / total, 0.012) << f.name() << " pixel " << x;
    }
  }
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

// Emission scaled past float range (gradcheck --emission-scale 1e38 made it inf) used to leave the
// power table empty and crash in sampling; a scene without emitters is still valid.
TEST(Render, LightSamplerRejectsNonFiniteEmissionAndAcceptsNone) {
  SynthScene cornell = makeSynthScene(SynthSceneKind::Cornell, 32);
  Scene scene(cornell.scene.mesh);
  Appearance a = cornell.scene.appearance;
  int emitter = -1;
  for (int o = 0; o < a.objectCount(); ++o)
    if (a.isEmissive(o)) emitter = o;
  ASSERT_GE(emitter, 0);
  a.emission[emitter] *= 1e38f;
  try {
    LightSampler lights(scene, a);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format("object {} ('{}') emits a non-finite power", emitter, a.names[emitter])),
              std::string::npos) << e.what();
  }
  for (Color& e : a.emission) e = Color::Zero();
  a.emissionTextureOf.assign(a.objectCount(), -1);
  EXPECT_TRUE(LightSampler(scene, a).empty());
}
