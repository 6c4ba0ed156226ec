#include <gtest/gtest.h>

#include <algorithm>

#include "core/error.h"
#include "params/parameters.h"

using namespace relume;

TEST(Parameters, ProjectionKeepsEveryGroupInItsDomain) {
  Appearance a(2);
  a.albedo = Texture(4, 4, Color(-0.2f, 0.5f, 1.7f));
  a.roughness = {0.0f, 3.0f};
  a.specular = {-1.0f, 0.4f};
  a.emission = {Color(-1, 2, 0), Color::Zero()};
  projectToDomain(a);
  EXPECT_EQ(a.albedo.texel(5)[0], 0.0f);
  EXPECT_EQ(a.albedo.texel(5)[2], 1.0f);
  EXPECT_EQ(a.roughness[0], kRoughnessMin);
  EXPECT_EQ(a.roughness[1], 1.0f);
  EXPECT_EQ(a.specular[0], 0.0f);
  EXPECT_EQ(a.emission[0][0], 0.0f);
  EXPECT_EQ(a.emission[0][1], 2.0f);
  EXPECT_GT(kRoughnessMin * kRoughnessMin, 1e-3f);  // r_min keeps alpha out of its clamp
}

namespace {
// Two triangles, objects 0 and 1, in separate uv windows.
TriangleMesh twoObjectMesh() {
  MeshData d;
  d.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {3, 0, 0}, {2, 1, 0}};
  d.uvs = {{0.1f, 0.1f}, {0.3f, 0.1f}, {0.1f, 0.3f}, {0.6f, 0.6f}, {0.9f, 0.6f}, {0.6f, 0.9f}};
  d.triangles = {{0, 1, 2}, {3, 4, 5}};
  d.faceObject = {0, 1};
  return buildMesh(d, "t");
}
}  // namespace

TEST(Parameters, EmissionTexturesOnlyForEmitters) {
  const TriangleMesh mesh = twoObjectMesh();
  Appearance a(2);
  a.emission[1] = Color(4, 5, 6);
  allocateEmissionTextures(a, mesh, 64, [](float, float) { return 1.0f; });
  EXPECT_EQ(a.emissionTextureOf[0], -1);
  ASSERT_EQ(a.emissionTextures.size(), 1u);
  const Texture& t = a.emissionTextures[0];
  EXPECT_LT(t.texelCount(), 64u * 64u / 4);  // a window, not the whole atlas
  EXPECT_TRUE(a.emissionAt(1, Vec2(0.7f, 0.7f)).isApprox(Color(4, 5, 6)));
  Gradients g(a);
  EXPECT_EQ(g.emissionTexture[0].size(), t.rgb.size());
  EXPECT_EQ(parseParamKind("emission_tex"), ParamKind::EmissionTexture);
  EXPECT_THROW(parseParamKind("metallic"), Error);
}

TEST(Gradients, ListsEverySplattedAlbedoTexelOnceAndClearZeroesEveryBuffer) {
  // The fit's mask, step and reset visit only the splatted texels: a texel missing from the list
  // would keep a stale gradient into the next iteration, or miss its step.
  const TriangleMesh mesh = twoObjectMesh();
  Appearance a(2);
  a.albedo = Texture(64, 64, Color::Constant(0.5f));
  a.emission[1] = Color(4, 5, 6);
  allocateEmissionTextures(a, mesh, 64, [](float, float) { return 1.0f; });
  Gradients g(a, true);
  const auto allZero = [&] {
    auto zero = [](const std::vector<float>& v) {
      return std::all_of(v.begin(), v.end(), [](float x) { return x == 0.0f; });
    };
    return zero(g.albedo) && zero(g.albedoCurvature) && zero(g.emissionTexture[0]) && zero(g.objects);
  };
  for (int round = 0; round < 2; ++round) {  // the second round reuses what the first cleared
    g.accumulate(3000, [&](Gradients::Chunk& chunk, size_t begin, size_t end) {
      for (size_t ray = begin; ray < end; ++ray) {
        const auto texel = static_cast<uint32_t>((ray * 7 + round) % 4096);
        if (ray % 3 != 2) chunk.addAlbedo(texel, Color::Constant(0.25f));
        if (ray % 3 != 0)
          chunk.addAlbedoCurvature((texel + 1) % 4096, Color::Constant(1.0f));  // some texels: curvature alone
        if (ray % 5 == 0)
          chunk.addEmissionTexel(0, static_cast<uint32_t>(ray % (g.emissionTexture[0].size() / 3)), Color::Ones());
        chunk.addRoughness(1, 0.5);
      }
    });
    std::vector<uint32_t> listed = g.splattedAlbedoTexels();
    std::sort(listed.begin(), listed.end());
    EXPECT_TRUE(std::adjacent_find(listed.begin(), listed.end()) == listed.end()) << "a texel listed twice";
    std::vector<uint32_t> nonZero;
    for (uint32_t t = 0; t < g.albedo.size() / 3; ++t)
      if (g.albedo[3 * t] != 0.0f || g.albedoCurvature[3 * t] != 0.0f) nonZero.push_back(t);
    EXPECT_EQ(listed, nonZero);
    EXPECT_FALSE(allZero());
    g.clear();
    EXPECT_TRUE(allZero());
    EXPECT_TRUE(g.splattedAlbedoTexels().empty());
  }
}
