#include "scene/segmentation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <set>

namespace relume {
namespace {

// A grid of n x n unit-ish quads spanning `u` and `v` from `origin`, appended to `d`. Every
// triangle gets its own three vertices (bit-identical positions where they meet), as meshes
// with per-face uv or normal seams have them, so connectivity must come from welding.
void addGrid(MeshData& d, const Vec3& origin, const Vec3& u, const Vec3& v, int n) {
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const auto at = [&](int a, int b) { return Vec3(origin + u * (float(a) / n) + v * (float(b) / n)); };
      for (const auto& tri : {std::array<std::pair<int, int>, 3>{{{i, j}, {i + 1, j}, {i + 1, j + 1}}},
                              std::array<std::pair<int, int>, 3>{{{i, j}, {i + 1, j + 1}, {i, j + 1}}}}) {
        const int base = static_cast<int>(d.positions.size());
        for (const auto& [a, b] : tri) d.positions.push_back(at(a, b));
        d.triangles.emplace_back(base, base + 1, base + 2);
      }
    }
}

Vec3 centroid(const TriangleMesh& m, size_t f) {
  return (m.positions[m.triangles[f][0]] + m.positions[m.triangles[f][1]] + m.positions[m.triangles[f][2]]) / 3.0f;
}

// Every face observed, with radiance radiance(centroid) and log standard error `error`.
std::vector<FaceAppearance> observedAs(const TriangleMesh& m, const std::function<Color(const Vec3&)>& radiance,
                                       float error = 0.02f) {
  std::vector<FaceAppearance> a(m.triangles.size());
  for (size_t f = 0; f < a.size(); ++f) {
    a[f].observed = true;
    a[f].logRadiance = radiance(centroid(m, f)).log();
    a[f].logError = Color::Constant(error);
  }
  return a;
}

size_t objectsWhere(const TriangleMesh& m, const Segmentation& s, const std::function<bool(const Vec3&)>& inside) {
  std::set<int> ids;
  for (size_t f = 0; f < m.triangles.size(); ++f)
    if (inside(centroid(m, f))) ids.insert(s.faceObject[f]);
  return ids.size();
}

TriangleMesh floorMesh(int n = 20) {
  MeshData d;
  addGrid(d, Vec3(0, 0, 0), Vec3(4, 0, 0), Vec3(0, 0, 4), n);
  return buildMesh(d, "floor");
}

TEST(Segmentation, ALampFusedIntoTheCeilingIsItsOwnObject) {
  const TriangleMesh m = floorMesh();
  const auto lamp = [](const Vec3& p) { return p.x() > 1.6f && p.x() < 2.4f && p.z() > 1.6f && p.z() < 2.4f; };
  const Segmentation s =
      segmentMesh(m, observedAs(m, [&](const Vec3& p) { return Color::Constant(lamp(p) ? 12.0f : 0.3f); }), {});
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.objects, 2);
  EXPECT_EQ(objectsWhere(m, s, lamp), 1u);
  EXPECT_EQ(objectsWhere(m, s, [&](const Vec3& p) { return !lamp(p); }), 1u);
  // Unseen, the same ceiling is one object.
  EXPECT_EQ(segmentMesh(m, std::vector<FaceAppearance>(m.triangles.size()), {}).objects, 1);
}

TEST(Segmentation, ShadingRampsStayOneObjectButARampOfMixedFacesCannotChainALampOn) {
  const TriangleMesh m = floorMesh(40);
  // The radiance falls by 3x across the floor, smoothly: one object.
  Segmentation s = segmentMesh(
      m, observedAs(m, [](const Vec3& p) { return Color::Constant(0.9f * std::exp(-std::log(3.0f) * p.x() / 4)); }),
      {});
  EXPECT_EQ(s.objects, 1);
  // The ceiling (x < 1, 0.3) reaches a lamp (x > 3, 12) by 20 steps of 1.2x, each within
  // `edgeContrast` (blurred faces around a lamp look like this): the regions' means part them.
  const float ratio = std::pow(40.0f, 1.0f / 20);
  s = segmentMesh(m, observedAs(m, [&](const Vec3& p) {
                    if (p.x() < 1) return Color::Constant(0.3f);
                    if (p.x() > 3) return Color::Constant(12.0f);
                    return Color::Constant(0.3f * std::pow(ratio, std::floor((p.x() - 1) / 0.1f) + 1));
                  }),
                  {});
  EXPECT_GE(s.objects, 2);
  std::set<int> dark, bright;
  for (size_t f = 0; f < m.triangles.size(); ++f) {
    if (centroid(m, f).x() < 1) dark.insert(s.faceObject[f]);
    if (centroid(m, f).x() > 3) bright.insert(s.faceObject[f]);
  }
  EXPECT_EQ(dark.size(), 1u);
  for (int id : bright) EXPECT_EQ(dark.count(id), 0u) << "the lamp shares object " << id << " with the ceiling";
}

TEST(Segmentation, CreasesPartSurfacesOfOneColourButNoiseAlongThemDoesNot) {
  MeshData d;
  addGrid(d, Vec3(0, 0, 0), Vec3(4, 0, 0), Vec3(0, 0, 4), 10);  // floor
  addGrid(d, Vec3(0, 0, 0), Vec3(0, 2.5f, 0), Vec3(4, 0, 0), 10);  // wall, along the floor's z = 0 edge
  TriangleMesh m = buildMesh(d, "corner");
  Segmentation s = segmentMesh(m, observedAs(m, [](const Vec3&) { return Color::Constant(0.5f); }), {});
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.objects, 2);
  // Vertex noise of up to 35% of a face's size along the floor's normal (a scan's 5 mm on 1.5 cm
  // faces) tilts neighbouring faces apart by more than the crease angle: on the smoothed normals
  // it is still two objects (on raw normals the floor falls apart).
  MeshData noisy = d;
  for (size_t v = 0; v < noisy.positions.size(); ++v)
    if (noisy.positions[v].y() == 0.0f && noisy.positions[v].x() > 0 && noisy.positions[v].z() > 0)
      noisy.positions[v].y() += 0.14f * std::sin(37.0f * noisy.positions[v].x() + 91.0f * noisy.positions[v].z());
  m = buildMesh(noisy, "noisy corner");
  s = segmentMesh(m, observedAs(m, [](const Vec3&) { return Color::Constant(0.5f); }), {});
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.objects, 2);
}

TEST(Segmentation, NoisyFacesJoinAndSmallRegionsMergeUnlessTheyOutshineTheirNeighbour) {
  const TriangleMesh m = floorMesh();
  // Faces whose radiance scatters by +-40% with a standard error that says so: one object.
  int i = 0;
  std::vector<FaceAppearance> a = observedAs(
      m, [&](const Vec3&) { return Color::Constant(0.5f * (1.0f + 0.4f * std::sin(1.7f * i++))); }, 0.25f);
  EXPECT_EQ(segmentMesh(m, a, {}).objects, 1);
  // Below 1% of the surface, a dark patch of two faces joins the floor; a bright one (10x its
  // neighbour) of the same size is kept.
  const auto patch = [](const Vec3& p, float x0) {
    return p.x() > x0 && p.x() < x0 + 0.2f && p.z() > 2 && p.z() < 2.2f;
  };
  a = observedAs(m, [&](const Vec3& p) {
    return Color::Constant(patch(p, 1.0f) ? 0.1f : patch(p, 3.0f) ? 5.0f : 0.5f);
  });
  SegmentationOptions o;
  o.minAreaFraction = 0.01f;
  const Segmentation s = segmentMesh(m, a, o);
  EXPECT_EQ(s.objects, 2);
  EXPECT_EQ(s.keptSmallBright, 1u);
  EXPECT_GE(s.mergedSmall, 1u);
  EXPECT_EQ(objectsWhere(m, s, [&](const Vec3& p) { return !patch(p, 3.0f); }), 1u);
  // Without the merge the dark patch stays apart.
  o.minAreaFraction = 0;
  EXPECT_EQ(segmentMesh(m, a, o).objects, 3);
}

TEST(Segmentation, AClippedPaneAndTheWhiteBlindBesideItArePartedByTheirClipping) {
  const TriangleMesh m = floorMesh();
  // The pane (x < 2) clips in every frame, so its radiance is the clip level's floor, 1.9; the
  // blind beside it shows 1.8 unclipped.
  std::vector<FaceAppearance> a =
      observedAs(m, [](const Vec3& p) { return Color::Constant(p.x() < 2 ? 1.9f : 1.8f); });
  for (size_t f = 0; f < a.size(); ++f) a[f].clippedFraction = centroid(m, f).x() < 2 ? 1.0f : 0.0f;
  EXPECT_EQ(segmentMesh(m, a, {}).objects, 2);
  for (auto& x : a) x.clippedFraction = 0;
  EXPECT_EQ(segmentMesh(m, a, {}).objects, 1);
  // A pane seen only clipped, whose faces' floors differ with the exposures of the frames that saw
  // them (1 in one half, 2.83 in the other): one object, the blind another.
  for (size_t f = 0; f < a.size(); ++f) {
    const Vec3 c = centroid(m, f);
    a[f].clippedFraction = c.x() < 2 ? 1.0f : 0.0f;
    a[f].logRadiance = Color::Constant(std::log(c.x() >= 2 ? 1.8f : c.z() < 2 ? 1.0f : 2.83f));
  }
  EXPECT_EQ(segmentMesh(m, a, {}).objects, 2);
}

TEST(Segmentation, SeparateComponentsStaySeparateAndIdsFollowTheFaces) {
  MeshData d;
  addGrid(d, Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1), 4);
  addGrid(d, Vec3(0, 0.5f, 0), Vec3(1, 0, 0), Vec3(0, 0, 1), 4);  // a parallel plate above it
  const TriangleMesh m = buildMesh(d, "plates");
  const Segmentation s = segmentMesh(m, observedAs(m, [](const Vec3&) { return Color::Constant(0.5f); }), {});
  EXPECT_EQ(s.components, 2u);
  EXPECT_EQ(s.objects, 2);
  EXPECT_EQ(s.isolatedSmall, 0u);
  EXPECT_EQ(s.faceObject.front(), 0);
  EXPECT_EQ(s.faceObject.back(), 1);
  const std::vector<uint32_t> c = connectedComponents(m);
  EXPECT_EQ(c.front(), 0u);
  EXPECT_EQ(c.back(), 1u);
}

}  // namespace
}  // namespace relume
