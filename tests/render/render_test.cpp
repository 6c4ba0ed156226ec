// Whole-renderer checks: white furnace, an analytic direct-lighting case, determinism.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>

#include "core/error.h"
#include "scenes/synth.h"
#include "render/film.h"

using namespace relume;

namespace {

Color meanRadiance(const Scene& scene, const Appearance& a, const Vec3& origin, const Vec3& dir, int paths,
                   int maxDepth, double* stdError = nullptr) {
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
      const Color L =
          meanRadiance(scene, a, Vec3(0.1f, 0.2f, -0.1f), Vec3(0.3f, 0.5f, 0.8f).normalized(), 20000, depth, &se);
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
  m.positions = {receiver + Vec3(-6, 0, -6), receiver + Vec3(6, 0, -6), receiver + Vec3(6, 0, 6),
                 receiver + Vec3(-6, 0, 6),  c + Vec3(-h, 0, -h),       c + Vec3(h, 0, -h),
                 c + Vec3(h, 0, h),          c + Vec3(-h, 0, h)};
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

TEST(Render, SmallEmitterAnalyticIrradiance) { expectDirectLightingMatches(Vec3::Zero(), 0, 0); }

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
  for (const PixelFilter& f : {PixelFilter(), PixelFilter(PixelFilterType::BlackmanHarris, 1.5f),
                               PixelFilter(PixelFilterType::Gaussian, 1.5f)}) {
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

// Every event a path reports, in order, with its values (a differentiating observer, so the
// zero-valued events are reported too).
struct EventLog : NullPathObserver {
  static constexpr bool kDifferentiating = true;
  std::vector<float> log;
  int vertices = 0;
  void put(std::initializer_list<float> v) { log.insert(log.end(), v); }
  void traced(const Vec3& o, const Vec3& d, float tmax, bool shadow) {
    put({1, o.x(), o.y(), o.z(), d.x(), d.y(), d.z(), tmax, float(shadow)});
  }
  void vertex(int depth, const SurfaceHit& hit, const ShadingFrame&, const Vec3& wo, const Color& beta) {
    ++vertices;
    put({2, float(depth), hit.p.x(), hit.p.y(), hit.p.z(), hit.uv.x(), hit.uv.y(), float(hit.object), wo.z(), beta[0],
         beta[1], beta[2]});
  }
  void emission(int depth, const SurfaceHit&, float mis, const Color& le) {
    put({3, float(depth), mis, le[0], le[1], le[2]});
  }
  void nee(int depth, const Vec3& wi, const Color& f, float cosI, float scale, const Color& le,
           const SurfaceHit& light) {
    put({4, float(depth), wi.z(), f[0], f[1], f[2], cosI, scale, le[0], float(light.object)});
  }
  void scatter(int depth, const Vec3& wi, const Color& f, float cosI, float pdf, float survival) {
    put({5, float(depth), wi.x(), wi.z(), f[0], f[1], f[2], cosI, pdf, survival});
  }
};

// A wavefront interleaves its paths bounce by bounce; each path must still do exactly what it does
// traced alone (same hits, random numbers, events and estimate), whatever the wave's width and
// whichever of its neighbours end early (roulette, escaping rays, cameras rays that miss).
TEST(Render, AWavefrontTracesEachPathExactlyAsItIsTracedAlone) {
  SynthScene room = makeSynthScene(SynthSceneKind::Room, 256);
  Scene scene(room.scene.mesh);
  const Appearance& a = room.scene.appearance;
  LightSampler lights(scene, a);
  const AppearanceScope scope = AppearanceScope::uniform(a);
  const Camera cam = synthCameraPath(SynthSceneKind::Room, 8, 24, 16, 0.0)[2];
  PathSettings settings;
  settings.russianRoulette = true;
  settings.rouletteDepth = 2;
  std::vector<PathSlot> alone;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x) {
      const CameraSample cs = cameraSample(cam, x, y, 0, 5);
      ASSERT_TRUE(cs.dir);
      // Every third ray starts far outside the room, pointing away from it: it hits nothing.
      const bool away = (x + y) % 3 == 0;
      alone.emplace_back(away ? Vec3(cam.position - 100.0f * *cs.dir) : cam.position, away ? Vec3(-*cs.dir) : *cs.dir,
                         cs.rng);
    }
  std::vector<EventLog> aloneLogs(alone.size());
  std::vector<SurfaceHit> aloneFirst(alone.size());
  for (size_t i = 0; i < alone.size(); ++i) {
    Pcg32 rng = alone[i].rng;
    alone[i].L =
        tracePath(scene, lights, scope, settings, alone[i].origin, alone[i].dir, rng, aloneLogs[i], &aloneFirst[i]);
  }
  int missed = 0, ended = 0, deep = 0;
  for (const EventLog& e : aloneLogs)
    missed += e.vertices == 0, ended += e.vertices > 0 && e.vertices < 4, deep += e.vertices >= 6;
  EXPECT_GT(missed, 50);  // neighbours that end at once, early (roulette), and late
  EXPECT_GT(ended, 10);
  EXPECT_GT(deep, 10);
  for (size_t width : {size_t{1}, size_t{7}, alone.size()}) {
    for (size_t b = 0; b < alone.size(); b += width) {
      const size_t n = std::min(width, alone.size() - b);
      std::vector<PathSlot> wave;
      std::vector<EventLog> logs(n);
      std::vector<SurfaceHit> first(n);
      for (size_t i = 0; i < n; ++i)
        wave.emplace_back(alone[b + i].origin, alone[b + i].dir, alone[b + i].rng, &first[i]);
      tracePaths(scene, lights, scope, settings, std::span<PathSlot>(wave),
                 [&](size_t i) -> EventLog& { return logs[i]; });
      for (size_t i = 0; i < n; ++i) {
        SCOPED_TRACE(::testing::Message() << "width " << width << " path " << b + i);
        EXPECT_EQ(0, std::memcmp(wave[i].L.data(), alone[b + i].L.data(), sizeof(Color)));
        EXPECT_EQ(logs[i].log, aloneLogs[b + i].log);
        EXPECT_EQ(first[i].prim, aloneFirst[b + i].prim);
        EXPECT_EQ(first[i].t, aloneFirst[b + i].t);
      }
    }
  }
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
    EXPECT_NE(
        std::string(e.what()).find(fmt::format("object {} ('{}') emits a non-finite power", emitter, a.names[emitter])),
        std::string::npos)
        << e.what();
  }
  for (Color& e : a.emission) e = Color::Zero();
  a.emissionTextureOf.assign(a.objectCount(), -1);
  EXPECT_TRUE(LightSampler(scene, a).empty());
}

namespace {
// Object 0: a fan of triangles of 7 different sizes around the origin (so an alias table over them
// takes its aliases); objects 1 and 2: one triangle each; tilted vertex normals.
MeshData lightFan() {
  MeshData d;
  constexpr int kFan = 60;
  d.positions.push_back(Vec3::Zero());
  for (int k = 0; k <= kFan; ++k) {
    const float phi = 2.0f * kPi * static_cast<float>(k) / kFan, r = 0.5f + 0.3f * static_cast<float>(k % 7);
    d.positions.emplace_back(r * std::cos(phi), r * std::sin(phi), 0.0f);
  }
  for (int k = 0; k < kFan; ++k) d.triangles.emplace_back(0, k + 1, k + 2), d.faceObject.push_back(0);
  const int n = static_cast<int>(d.positions.size());
  d.positions.insert(d.positions.end(), {{0, 0, 2}, {1, 0, 2}, {0, 1, 2}, {5, 5, 0}, {6, 5, 0}, {5, 6, 0}});
  d.triangles.emplace_back(n, n + 2, n + 1), d.faceObject.push_back(1);
  d.triangles.emplace_back(n + 3, n + 4, n + 5), d.faceObject.push_back(2);
  for (size_t v = 0; v < d.positions.size(); ++v)
    d.normals.push_back(Vec3(0.1f * static_cast<float>(v % 5), 0.2f, 1.0f).normalized());
  return d;
}
}  // namespace

// Light points: an emitter by power, a triangle by area, a uniform point whose position and
// attributes (shading normal from tilted vertex normals included) are the mesh's at that point.
TEST(Render, LightPointsFollowPowerThenAreaAndLieOnTheMesh) {
  const Scene scene(buildMesh(lightFan(), "fan"));
  const TriangleMesh& mesh = scene.mesh();
  Appearance a(3);
  a.emission[0] = Color::Constant(1.0f);
  a.emission[1] = Color(2.0f, 3.0f, 4.0f);  // object 2: not a light
  const LightSampler lights(scene, a);

  std::vector<double> objectArea(3, 0.0), objectPower(3, 0.0);
  for (size_t f = 0; f < mesh.triangles.size(); ++f) objectArea[mesh.faceObject[f]] += mesh.faceArea[f];
  for (int o = 0; o < 3; ++o) objectPower[o] = objectArea[o] * luminance(a.emission[o]);
  const double power = objectPower[0] + objectPower[1];
  EXPECT_NEAR(lights.pdfArea(0) * objectArea[0] + lights.pdfArea(1) * objectArea[1], 1.0, 1e-5);
  EXPECT_EQ(lights.pdfArea(2), 0.0f);

  constexpr int kSamples = 400000;
  std::vector<int> count(mesh.triangles.size(), 0);
  Pcg32 rng(7);
  for (int i = 0; i < kSamples; ++i) {
    const float uObject = rng.next1D(), uTriangle = rng.next1D();
    const Vec2 uPoint = rng.next2D();
    const LightSample s =
        lights.sampleAt(lights.pickTriangle(lights.pickEmitter(uObject, uTriangle), uTriangle), uPoint);
    const uint32_t f = s.hit.prim;
    ++count[f];
    const Vec2 b = squareToTriangle(uPoint);
    const auto& v = mesh.triangles[f];
    const Vec3 p = barycentricPoint(mesh.positions[v[0]], mesh.positions[v[1]], mesh.positions[v[2]], b.x(), b.y());
    ASSERT_EQ(0, std::memcmp(s.hit.p.data(), p.data(), sizeof(Vec3))) << "triangle " << f;
    const SurfaceHit expected = scene.hitFromFace(f, b.x(), b.y());
    ASSERT_EQ(s.hit.ng, expected.ng);
    ASSERT_EQ(s.hit.ns, expected.ns);
    ASSERT_EQ(s.hit.uv, expected.uv);
    ASSERT_EQ(s.hit.object, mesh.faceObject[f]);
    ASSERT_EQ(s.pdfArea, lights.pdfArea(s.hit.object));
  }
  for (size_t f = 0; f < count.size(); ++f) {
    const int o = mesh.faceObject[f];
    const double p = objectPower[o] / power * mesh.faceArea[f] / objectArea[o];
    const double expected = kSamples * p;
    EXPECT_LE(std::abs(count[f] - expected), 5.0 * std::sqrt(expected * (1 - p)) + 1e-9)
        << "triangle " << f << " of object " << o;
  }
}

// A sampler built from the previous one (a fit's, every iteration) samples exactly as one built
// afresh, as emitters change power, go dark and come back, and builds only the tables of objects
// that never emitted before.
TEST(Render, LightSamplerFromThePreviousOneSamplesAsAFreshOne) {
  const Scene scene(buildMesh(lightFan(), "fan"));
  Appearance a(3);
  a.emission[0] = Color::Constant(1.0f);
  a.emission[1] = Color(2.0f, 3.0f, 4.0f);
  LightSampler previous(scene, a);
  EXPECT_EQ(previous.builtTables(), 2u);
  struct Step {
    std::array<Color, 3> emission;
    size_t built;  // tables the step builds
  };
  const std::vector<Step> steps = {
      {{Color::Constant(3.0f), Color::Zero(), Color(0.5f, 1.0f, 2.0f)}, 1},    // 0 brighter, 1 dark, 2 lit: 2 is new
      {{Color::Zero(), Color(1.0f, 1.0f, 1.0f), Color(0.5f, 1.0f, 2.0f)}, 0},  // 0 dark, 1 back: kept while dark
      {{Color::Constant(0.2f), Color(1.0f, 1.0f, 1.0f), Color::Zero()}, 0},
  };
  for (const Step& step : steps) {
    for (int o = 0; o < 3; ++o) a.emission[o] = step.emission[o];
    LightSampler reused(scene, a, &previous);
    const LightSampler fresh(scene, a);
    EXPECT_EQ(reused.builtTables(), step.built);
    for (int o = 0; o < 3; ++o) ASSERT_EQ(reused.pdfArea(o), fresh.pdfArea(o)) << "object " << o;
    Pcg32 rng(11);
    for (int i = 0; i < 20000; ++i) {
      const float uObject = rng.next1D(), uTriangle = rng.next1D();
      const Vec2 uPoint = rng.next2D();
      auto point = [&](const LightSampler& l) {
        return l.sampleAt(l.pickTriangle(l.pickEmitter(uObject, uTriangle), uTriangle), uPoint);
      };
      const LightSample r = point(reused), f = point(fresh);
      ASSERT_EQ(r.hit.prim, f.hit.prim);
      ASSERT_EQ(r.hit.p, f.hit.p);
      ASSERT_EQ(r.pdfArea, f.pdfArea);
    }
    previous = std::move(reused);
  }
}
