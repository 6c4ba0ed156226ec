// Cameras at grazing angles and 1 cm from a surface, and degenerate and sliver triangles.
#include "extremes.h"

#include "capture/frame_store.h"
#include "capture/transforms.h"
#include "io/image.h"
#include "render/film.h"
#include "sampling/samplers.h"
#include "sampling/visibility.h"
#include "scene/texel_map.h"

using namespace relume;
using namespace relume::extremes;
namespace fs = std::filesystem;

namespace {

// The texel-to-ray Jacobian is omitted (weight 1), so nothing geometric multiplies a ray's loss:
// the batch loss is exactly the mean of the squared residuals of the primal estimates, however
// close or slanted the camera. (Its cos / d^2 would be 1e4 at 1 cm and 0 at grazing.)
void expectPlainMeanLoss(const Scene& scene, const Appearance& a, const std::vector<BatchRay>& rays) {
  const LightSampler lights(scene, a);
  AdjointSettings s;
  s.path.maxDepth = 4;
  Gradients g(a, true);
  const double loss = computeGradients(scene, a, lights, rays, s, 0, g).loss;
  EXPECT_TRUE(allFinite(g));
  const std::vector<Color> est = estimates(scene, a, rays, 4);
  double mean = 0;
  for (size_t j = 0; j < rays.size(); ++j) mean += rayLoss(est[j], rays[j]) / rays.size();
  EXPECT_NEAR(loss, mean, 1e-5 * mean);
  EXPECT_GT(mean, 0.0);
}

// The Cornell batch re-aimed by `aim(j)` = (origin, direction), references rendered from the truth.
GradientExperiment reaimed(const std::function<std::pair<Vec3, Vec3>(size_t)>& aim) {
  GradientExperiment e = cornell();
  for (size_t j = 0; j < e.rays.size(); ++j) std::tie(e.rays[j].origin, e.rays[j].dir) = aim(j);
  const Scene scene(e.truth.mesh);
  const std::vector<Color> reference = estimates(scene, e.truth.appearance, e.rays, 4, 99);
  for (size_t j = 0; j < e.rays.size(); ++j) e.rays[j].reference = reference[j];
  return e;
}

}  // namespace

TEST(ExtremeCameras, GrazingAndOneCentimetreFromTheFloor) {
  // The floor is y = 0, x and z in [0, 2] (Cornell); points between the boxes and the front wall,
  // seen along -z from within 0.5 m: no box in between.
  auto floorPoint = [](size_t j) {
    return Vec3(0.2f + 0.8f * ((j * 37) % 64) / 64.0f, 0.0f, 1.1f + 0.35f * ((j * 11) % 16) / 16.0f);
  };
  const GradientExperiment grazing = reaimed([&](size_t j) {
    const float angle = (85.0f + 4.9f * (j % 16) / 15.0f) * kPi / 180.0f;  // 85 to 89.9 degrees from the normal
    const Vec3 dir(0.0f, -std::cos(angle), -std::sin(angle));
    return std::pair{Vec3(floorPoint(j) - 0.5f * dir), dir};
  });
  const GradientExperiment close = reaimed([&](size_t j) {
    const float tilt = 0.6f * ((j * 7) % 16) / 15.0f - 0.3f;  // a fan of +-17 degrees
    const Vec3 dir = Vec3(tilt, -1.0f, 0.5f * tilt).normalized();
    return std::pair{Vec3(floorPoint(j) - 0.01f / -dir.y() * dir), dir};  // 1 cm above the floor
  });
  for (const auto* e : {&grazing, &close}) {
    const std::string what = e == &grazing ? "grazing" : "1 cm";
    expectPlainMeanLoss(Scene(e->truth.mesh), e->current, e->rays);
    // Bound: gradients within gradcheck's 2e-3 of the frozen-sampling finite difference.
    expectFiniteAndRight(*e, {ParamKind::Albedo, ParamKind::Roughness, ParamKind::Specular}, what);
  }
}

TEST(ExtremeGeometry, DegenerateTrianglesAreDroppedAndSliversAreRight) {
  // A floor (y = 0, object 0) under a ceiling light (y = 1, object 1); on the floor a sliver
  // 0.6 m long and 2 um wide (object 2), under the light a sliver light (object 3); plus a
  // collinear triangle and a needle 1e-7 as high as it is long.
  MeshData d;
  auto quad = [&](float y, bool up, int object) {
    const int b = static_cast<int>(d.positions.size());
    for (auto [x, z] : {std::pair{0.0f, 0.0f}, {1.0f, 0.0f}, {1.0f, 1.0f}, {0.0f, 1.0f}})
      d.positions.emplace_back(x, y, z);
    // Counter-clockwise seen from +y gives a normal +y.
    d.triangles.push_back(up ? Eigen::Vector3i(b, b + 3, b + 2) : Eigen::Vector3i(b, b + 2, b + 3));
    d.triangles.push_back(up ? Eigen::Vector3i(b, b + 2, b + 1) : Eigen::Vector3i(b, b + 1, b + 2));
    d.faceObject.insert(d.faceObject.end(), {object, object});
  };
  auto triangle = [&](Vec3 p0, Vec3 p1, Vec3 p2, int object) {
    const int b = static_cast<int>(d.positions.size());
    d.positions.insert(d.positions.end(), {p0, p1, p2});
    d.triangles.emplace_back(b, b + 1, b + 2);
    d.faceObject.push_back(object);
  };
  const float width = 2e-6f, y0 = 1e-3f, y1 = 1.0f - 1e-3f;
  quad(0.0f, true, 0);
  quad(1.0f, false, 1);
  triangle({0.2f, y0, 0.5f}, {0.5f, y0, 0.5f + width}, {0.8f, y0, 0.5f}, 2);        // normal +y
  triangle({0.2f, y1, 0.5f}, {0.8f, y1, 0.5f}, {0.5f, y1, 0.5f + width}, 3);        // normal -y
  triangle({0.1f, 0.5f, 0.1f}, {0.2f, 0.5f, 0.2f}, {0.3f, 0.5f, 0.3f}, 0);          // collinear
  triangle({0.1f, 0.5f, 0.9f}, {0.9f, 0.5f, 0.9f}, {0.5f, 0.5f, 0.9f + 1e-7f}, 0);  // needle
  SceneDescription truth{{}, buildMesh(d, "slivers"), Appearance(4)};
  EXPECT_EQ(truth.mesh.droppedDegenerate, 2u);
  ASSERT_EQ(truth.mesh.triangles.size(), 6u);
  Appearance& a = truth.appearance;
  a.emission[1] = Color::Constant(2.0f);
  a.emission[3] = Color::Constant(5e4f);  // a sliver light as bright as the panel: same power order
  for (int o = 0; o < 4; ++o) a.roughness[o] = 0.3f, a.specular[o] = 0.5f, a.albedoConstant[o] = Color::Constant(0.6f);
  // Rays straight down onto the floor sliver, and up into the light's, at a third of the width
  // (2 um at x = 0.5): inside wherever |x - 0.5| < 0.2.
  GradientExperiment e{std::move(truth), Appearance(), {}};
  for (int j = 0; j < 64; ++j) {
    const float x = 0.35f + 0.3f * j / 63.0f;
    const bool down = j % 2 == 0;
    e.rays.push_back({Vec3(x, 0.5f, 0.5f + width / 3), Vec3(0.0f, down ? -1.0f : 1.0f, 0.0f), Color::Zero(), {}});
  }
  const Scene scene(e.truth.mesh);
  for (const BatchRay& r : e.rays) {
    const auto hit = scene.intersect(r.origin, r.dir);
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->object, r.dir.y() < 0 ? 2 : 3);  // the slivers are hit, not what lies behind them
  }
  const std::vector<Color> reference = estimates(scene, e.truth.appearance, e.rays, 4, 99);
  for (size_t j = 0; j < e.rays.size(); ++j) e.rays[j].reference = reference[j];
  e.current = perturbAppearance(e.truth.appearance, 7);
  // Bound: gradients within gradcheck's 2e-3 of the frozen-sampling finite difference, the sliver
  // light's included (its area pdf is 1/6e-7).
  const GradcheckReport r =
      expectFiniteAndRight(e, {ParamKind::Roughness, ParamKind::Specular, ParamKind::Emission}, "slivers");
  auto checked = [&](ParamKind kind, int object) {
    return std::any_of(r.rows.begin(), r.rows.end(),
                       [&](const GradcheckRow& row) { return row.param.kind == kind && row.param.object == object; });
  };
  EXPECT_TRUE(checked(ParamKind::Roughness, 2) && checked(ParamKind::Emission, 3)) << r.table();
}

TEST(ExtremeCameras, ACaptureWithFramesOneCentimetreFromAWallAndGrazingTheFloor) {
  // Frames 0 and 1 move 1 cm in front of the back wall (z = 0), looking along it 31 degrees
  // towards it (they see it from 1.1 cm on: a frame that sees only a few cm of surface gets no
  // visibility tile, which samples 6 points per 32^2 texels); frames 2 and 3 move 2 cm above the
  // floor looking along it (up to 89.9 degrees from its normal). Each pair 5 cm apart, so prepare
  // sees no motion blur. All are re-rendered from the truth, then prepared and sampled.
  const Vec3 closePosition(1.0f, 1.0f, 0.01f), grazingPosition(1.0f, 0.02f, 1.9f);
  const fs::path dir = tinyCapture("cameras", 4, [&](const fs::path& capture) {
    Capture cap = readTransforms(capture / "transforms.json");
    const SceneDescription truth = loadSceneFile(capture / "gt" / "scene.json");
    const Scene scene(truth.mesh);
    const LightSampler lights(scene, truth.appearance);
    auto place = [&](Frame& f, const Vec3& position, const Vec3& forward) {
      f.camera.position = position;
      f.camera.rotation.col(2) = forward.normalized();
      f.camera.rotation.col(1) = Vec3(0.0f, -1.0f, 0.0f);
      f.camera.rotation.col(0) = f.camera.rotation.col(1).cross(f.camera.rotation.col(2));
      RenderOptions o;
      o.spp = 4;
      writeExr(f.image, renderImage(scene, truth.appearance, lights, f.camera, o).color);
    };
    for (int i = 0; i < 4; ++i)
      place(cap.frames[i], (i < 2 ? closePosition : grazingPosition) + Vec3(0.05f * (i % 2), 0.0f, 0.0f),
            i < 2 ? Vec3(1.0f, 0.0f, -0.6f) : Vec3(0.0f, 0.0f, -1.0f));
    writeTransforms(capture / "transforms.json", cap.frames);
  });
  const fs::path work = dir / "work";
  const TriangleMesh mesh = loadMesh(work / "atlas_mesh.ply");
  const Scene scene(mesh);
  const TexelMap map(mesh, 64);
  const VisibilityIndex vis = VisibilityIndex::read(work / "visibility.bin");
  const Capture cap = readTransforms(dir / "capture" / "transforms.json");
  const FrameStore store(work / "frames.bin");
  std::vector<uint32_t> texels;
  for (size_t t = 0; t < map.texelCount(); ++t)
    if (map.covered(t)) texels.push_back(static_cast<uint32_t>(t));
  ASSERT_EQ(readJson(work / "prepare.json")["phases"]["frames"]["kept"].size(), 4u);
  const TextureSpaceSampler sampler(scene, map, texels, vis, {&cap.frames, &store, {0, 1, 2, 3}});
  // Four batches as large as the texel count, all four frames: each connection of weight 1 (no
  // Jacobian). The atlas texel is ~10 cm, so few texels lie within 10 cm of the wall cameras.
  std::vector<BatchRay> close, grazing;
  for (uint64_t it = 0; it < 4; ++it)
    for (const BatchRay& r : sampler.sample(1, it, {static_cast<int>(texels.size()), 4}).rays) {
      EXPECT_EQ(r.weight, 1.0f);
      EXPECT_TRUE(r.reference.allFinite() && r.reference.minCoeff() >= 0.0f);
      (r.origin.z() < 0.5f ? close : grazing).push_back(r);
    }
  ASSERT_GT(close.size(), 0u);
  ASSERT_GT(grazing.size(), 0u);
  float nearest = INFINITY, mostGrazing = 1;
  for (const BatchRay& r : close) nearest = std::min(nearest, scene.intersect(r.origin, r.dir)->t);
  for (const BatchRay& r : grazing)
    mostGrazing = std::min(mostGrazing, std::abs(scene.intersect(r.origin, r.dir)->ng.dot(r.dir)));
  EXPECT_LT(nearest, 0.1f);      // texels within 10 cm (a Jacobian's 1 / d^2 would be >= 100)
  EXPECT_LT(mostGrazing, 0.1f);  // and seen at more than 84 degrees (its cos would be < 0.1)
  const SceneDescription truth = loadSceneFile(dir / "capture" / "gt" / "scene.json");
  Appearance current = perturbAppearance(truth.appearance, 7);
  for (const auto* rays : {&close, &grazing}) expectPlainMeanLoss(scene, current, *rays);
  runFit(work, tinyFit(), false);
  expectBoundedFit(dir);
}
