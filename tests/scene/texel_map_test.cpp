#include <gtest/gtest.h>

#include <filesystem>
#include <array>
#include <functional>
#include <map>
#include <numeric>

#include "core/rng.h"
#include "core/system.h"
#include "core/warp.h"
#include "scenes/synth.h"
#include "scene/atlas.h"
#include "scene/texel_map.h"
#include "framed_room.h"

using namespace relume;

namespace {
TriangleMesh roomAtlas() {
  TriangleMesh mesh = makeSynthScene(SynthSceneKind::Room, 256).scene.mesh;
  mesh.uvs.clear();
  return buildAtlas(mesh, {});
}

TEST(TexelMap, CoveredTexelPointsMapBackIntoTheirTexel) {
  const TriangleMesh mesh = roomAtlas();
  const TexelMap map(mesh, 1024);
  ASSERT_GT(map.coveredCount(), 100000u);
  size_t checked = 0;
  for (size_t i = 0; i < map.texelCount(); i += 7) {
    if (!map.covered(i)) continue;
    const auto& t = mesh.triangles[map.triangle(i)];
    const Vec3 bc = map.barycentrics(mesh, i);
    const Vec2 uv = bc[0] * mesh.uvs[t[0]] + bc[1] * mesh.uvs[t[1]] + bc[2] * mesh.uvs[t[2]];
    const size_t back = static_cast<size_t>(uv.y() * 1024) * 1024 + static_cast<size_t>(uv.x() * 1024);
    ASSERT_EQ(back, i);
    // And the 3D point lies on that triangle's plane, inside it.
    const Vec3 p = map.point(mesh, i);
    EXPECT_LT(std::abs((p - mesh.positions[t[0]]).dot(mesh.faceNormal(map.triangle(i)))), 1e-4f);
    EXPECT_GE(bc.minCoeff(), -1e-5f);
    ++checked;
  }
  EXPECT_GT(checked, 10000u);
}

// Chart of every face: the connected components of the uv mesh, where two vertices are one when
// they have the same position and the same uv (a chart keeps the mesh's own vertex splits, e.g.
// along normal seams; the atlas splits vertices along chart seams).
std::vector<int> chartOfFace(const TriangleMesh& mesh) {
  std::map<std::array<float, 5>, int> weld;
  std::vector<int> id(mesh.positions.size());
  for (size_t v = 0; v < id.size(); ++v) {
    const Vec3& p = mesh.positions[v];
    const Vec2& uv = mesh.uvs[v];
    id[v] = weld.emplace(std::array<float, 5>{p.x(), p.y(), p.z(), uv.x(), uv.y()}, static_cast<int>(weld.size()))
                .first->second;
  }
  std::vector<int> parent(weld.size());
  std::iota(parent.begin(), parent.end(), 0);
  std::function<int(int)> root = [&](int v) { return parent[v] == v ? v : parent[v] = root(parent[v]); };
  for (const auto& t : mesh.triangles)
    for (int k = 1; k < 3; ++k) parent[root(id[t[k]])] = root(id[t[0]]);
  std::vector<int> chart(mesh.triangles.size());
  for (size_t f = 0; f < chart.size(); ++f) chart[f] = root(id[mesh.triangles[f][0]]);
  return chart;
}

// The gutter at every stage resolution: every texel of the bilinear footprint of every surface point
// is valid and holds a triangle of the point's own chart, so lookups and gradient scatters never mix
// two charts; except between tiny charts of one object, which share blocks (under
// AtlasOptions::sharedBlockTexels or sharedBlockWidth at the full-atlas density, so under them at
// 1024 too).
void expectFootprintsInsideTheirChart(const TriangleMesh& mesh, int samples) {
  const std::vector<int> chart = chartOfFace(mesh);
  std::map<int, double> texelsOfChart;  // uv area at 1024^2
  std::map<int, Eigen::AlignedBox2f> boxOfChart;
  for (size_t f = 0; f < chart.size(); ++f) {
    const auto& t = mesh.triangles[f];
    const Vec2 a = mesh.uvs[t[1]] - mesh.uvs[t[0]], b = mesh.uvs[t[2]] - mesh.uvs[t[0]];
    texelsOfChart[chart[f]] += 0.5 * std::abs(double(a.x()) * b.y() - double(a.y()) * b.x()) * 1024 * 1024;
    for (int k = 0; k < 3; ++k) boxOfChart[chart[f]].extend(mesh.uvs[t[k]] * 1024.0f);
  }
  const AtlasOptions o;
  auto tiny = [&](int c) {
    return texelsOfChart[c] < o.sharedBlockTexels || boxOfChart[c].sizes().minCoeff() < o.sharedBlockWidth;
  };
  auto shareable = [&](uint32_t f, uint32_t g) {
    return chart[f] == chart[g] || (mesh.faceObject[f] == mesh.faceObject[g] && tiny(chart[f]) && tiny(chart[g]));
  };
  for (int res : {1024, 2048, 4096}) {
    const TexelMap map(mesh, res);
    Pcg32 rng(5);
    for (int i = 0; i < samples; ++i) {
      const uint32_t f = rng.nextU32() % mesh.triangles.size();
      const Vec2 b = squareToTriangle(rng.next2D());
      const auto& t = mesh.triangles[f];
      const Vec2 uv = (1 - b.x() - b.y()) * mesh.uvs[t[0]] + b.x() * mesh.uvs[t[1]] + b.y() * mesh.uvs[t[2]];
      const float x = uv.x() * res - 0.5f, y = uv.y() * res - 0.5f;
      for (int dy = 0; dy <= 1; ++dy)
        for (int dx = 0; dx <= 1; ++dx) {
          const int tx = std::clamp(static_cast<int>(std::floor(x)) + dx, 0, res - 1);
          const int ty = std::clamp(static_cast<int>(std::floor(y)) + dy, 0, res - 1);
          const size_t texel = static_cast<size_t>(ty) * res + tx;
          ASSERT_TRUE(map.valid(texel)) << "res " << res;
          ASSERT_TRUE(shareable(map.triangle(texel), f)) << "res " << res << " face " << f;
        }
    }
  }
}
}  // namespace

TEST(TexelMap, PointsOnTheSurfaceLandOnValidTexelsOfTheirOwnChart) {
  expectFootprintsInsideTheirChart(roomAtlas(), 20000);
}

TEST(TexelMap, GutterHoldsOnARealMeshAtEveryStage) {
  const TriangleMesh mesh = loadMesh(std::filesystem::path(RELUME_TEST_DATA) / "furnished_cut.ply");
  expectFootprintsInsideTheirChart(buildAtlas(mesh, {}), 20000);
}

TEST(TexelMap, GutterHoldsAroundSharedBlocksAndCutFrames) {
  expectFootprintsInsideTheirChart(buildAtlas(makeFramedRoom(), {}), 20000);
}

// 4 bytes a texel at 4096^2 (its build time: `relume profile --what visibility`).
TEST(TexelMap, SizeAt4096) {
  const TexelMap map(roomAtlas(), 4096);
  EXPECT_EQ(map.bytes(), 4096u * 4096u * 4u);
  EXPECT_GT(map.coveredCount(), 4096u * 4096u / 4);
}
