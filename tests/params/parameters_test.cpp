#include <gtest/gtest.h>

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

TEST(Parameters, EmissionTexturesOnlyForEmitters) {
  MeshData d;
  d.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {3, 0, 0}, {2, 1, 0}};
  d.uvs = {{0.1f, 0.1f}, {0.3f, 0.1f}, {0.1f, 0.3f}, {0.6f, 0.6f}, {0.9f, 0.6f}, {0.6f, 0.9f}};
  d.triangles = {{0, 1, 2}, {3, 4, 5}};
  d.faceObject = {0, 1};
  const TriangleMesh mesh = buildMesh(d, "t");
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
