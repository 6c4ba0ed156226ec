#include <gtest/gtest.h>

#include "pipeline/synth.h"
#include "scene/atlas.h"

using namespace relume;

namespace {
void expectSound(const TriangleMesh& in, const TriangleMesh& out) {
  ASSERT_EQ(out.triangles.size(), in.triangles.size());
  EXPECT_EQ(countUvOverlaps(out, 10), 0u);
  for (const Vec2& uv : out.uvs) ASSERT_TRUE(uv.minCoeff() >= 0.0f && uv.maxCoeff() <= 1.0f);
  for (size_t f = 0; f < out.triangles.size(); ++f) {
    const auto& t = out.triangles[f];
    const Vec2 a = out.uvs[t[1]] - out.uvs[t[0]], b = out.uvs[t[2]] - out.uvs[t[0]];
    ASSERT_GT(std::abs(a.x() * b.y() - a.y() * b.x()), 0.0f) << "face " << f << " has zero uv area";
    ASSERT_EQ(out.faceObject[f], in.faceObject[f]);
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(out.positions[t[k]].isApprox(in.positions[in.triangles[f][k]]));
  }
}
}  // namespace

TEST(Atlas, OverlapTestFindsOverlapsAndIgnoresTouching) {
  MeshData d;
  d.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  d.uvs = {{0, 0}, {0.5f, 0}, {0, 0.5f}, {0.5f, 0.5f}};
  d.triangles = {{0, 1, 2}, {1, 3, 2}};  // share an edge: not an overlap
  TriangleMesh m = buildMesh(d, "t");
  EXPECT_EQ(countUvOverlaps(m, 10), 0u);
  EXPECT_TRUE(hasValidUvAtlas(m));
  m.uvs[3] = Vec2(0.1f, 0.1f);  // folds the second triangle over the first
  EXPECT_EQ(countUvOverlaps(m, 10), 1u);
  EXPECT_FALSE(hasValidUvAtlas(m));
}

TEST(Atlas, KeepsValidInputUv) {
  const SynthScene room = makeSynthScene(SynthSceneKind::Cornell, 256);
  AtlasReport r;
  const TriangleMesh out = buildAtlas(room.scene.mesh, {}, &r);
  EXPECT_TRUE(r.keptInputUv);
  EXPECT_EQ(out.uvs, room.scene.mesh.uvs);
}

TEST(Atlas, RoomWithoutUvIsChartedPackedAndDeterministic) {
  TriangleMesh mesh = makeSynthScene(SynthSceneKind::Room, 256).scene.mesh;
  mesh.uvs.clear();
  AtlasOptions o;
  AtlasReport r;
  const TriangleMesh a = buildAtlas(mesh, o, &r);
  expectSound(mesh, a);
  EXPECT_GE(r.packingEfficiency, 0.6) << r.summary();
  EXPECT_GT(r.lscmCharts, 0u) << "the ball is curved";
  EXPECT_NEAR(r.stretchMedian, 1.0, 0.02) << r.summary();
  const TriangleMesh b = buildAtlas(mesh, o);
  EXPECT_EQ(a.uvs, b.uvs);
  EXPECT_EQ(a.triangles, b.triangles);
}

TEST(Atlas, NoisyScanLikeMeshOf500kTriangles) {
  const TriangleMesh mesh = makeScanLikeRoom(500000, 0.004f);
  ASSERT_GE(mesh.triangles.size(), 450000u);
  AtlasOptions o;
  AtlasReport r;
  const TriangleMesh a = buildAtlas(mesh, o, &r);
  std::printf("%zu triangles: %s\n", mesh.triangles.size(), r.summary().c_str());
  expectSound(mesh, a);
  EXPECT_GE(r.packingEfficiency, 0.6) << r.summary();
}
