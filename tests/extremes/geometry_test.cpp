// Cameras at grazing angles and 1 cm from a surface, and degenerate and sliver triangles.
#include "extremes.h"

using namespace relume;
using namespace relume::extremes;

namespace {

// The texel-to-ray Jacobian is omitted (weight 1), so nothing geometric multiplies a ray's loss:
// the batch loss is exactly the mean of the squared residuals of the primal estimates, however
// close or slanted the camera. (Its cos / d^2 would be 1e4 at 1 cm and 0 at grazing.)
void expectPlainMeanLoss(const GradientExperiment& e, const Appearance& a, const std::vector<BatchRay>& rays) {
  const Scene scene(e.truth.mesh);
  const LightSampler lights(scene, a);
  AdjointSettings s;
  s.path.maxDepth = 4;
  Gradients g(a);
  const double loss = computeGradients(scene, a, lights, rays, s, 0, g).loss;
  const std::vector<Color> est = estimates(scene, a, rays, 4);
  double mean = 0;
  for (size_t j = 0; j < rays.size(); ++j) mean += rayLoss(est[j], rays[j].reference, rays[j].clip) / rays.size();
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
  auto floorPoint = [](size_t j) { return Vec3(0.2f + 0.8f * ((j * 37) % 64) / 64.0f, 0.0f, 1.1f + 0.35f * ((j * 11) % 16) / 16.0f); };
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
    expectPlainMeanLoss(*e, e->current, e->rays);
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
    for (auto [x, z] : {std::pair{0.0f, 0.0f}, {1.0f, 0.0f}, {1.0f, 1.0f}, {0.0f, 1.0f}}) d.positions.emplace_back(x, y, z);
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
  triangle({0.2f, y0, 0.5f}, {0.5f, y0, 0.5f + width}, {0.8f, y0, 0.5f}, 2);  // normal +y
  triangle({0.2f, y1, 0.5f}, {0.8f, y1, 0.5f}, {0.5f, y1, 0.5f + width}, 3);  // normal -y
  triangle({0.1f, 0.5f, 0.1f}, {0.2f, 0.5f, 0.2f}, {0.3f, 0.5f, 0.3f}, 0);     // collinear
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
  const GradcheckReport r = expectFiniteAndRight(e, {ParamKind::Roughness, ParamKind::Specular, ParamKind::Emission}, "slivers");
  auto checked = [&](ParamKind kind, int object) {
    return std::any_of(r.rows.begin(), r.rows.end(), [&](const GradcheckRow& row) {
      return row.param.kind == kind && row.param.object == object;
    });
  };
  EXPECT_TRUE(checked(ParamKind::Roughness, 2) && checked(ParamKind::Emission, 3)) << r.table();
}
