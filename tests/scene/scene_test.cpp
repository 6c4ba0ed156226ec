#include <gtest/gtest.h>

#include "core/error.h"
#include "core/rng.h"
#include "scene/atlas.h"
#include "scene/scene.h"
#include "scene/texel_map.h"

using namespace relume;

namespace {
// One triangle in z = 0 (geometric normal +z) whose vertex normals cancel out on the segment
// b0 = b2, b1 = 1/2 (vertex 1's normal is the opposite of the other two), like the real meshes'
// triangles with two vertex normals more than 150 degrees apart; and one whose three vertex normals
// all face away from its geometric normal.
TriangleMesh opposedNormals() {
  MeshData d;
  d.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {3, 0, 0}, {2, 1, 0}};
  d.normals = {{0, 0, 1}, {0, 0, -1}, {0, 0, 1}, {0, 0, -1}, {0, 0, -1}, {0, 0, -1}};
  d.triangles = {{0, 1, 2}, {3, 4, 5}};
  return buildMesh(d, "opposed normals");
}
}  // namespace

TEST(Scene, ShadingNormalThatVanishesFallsBackToTheGeometricNormal) {
  const TriangleMesh mesh = opposedNormals();
  // Exactly where the interpolation is zero (the old code normalised it to NaN) and next to it.
  for (const Vec3& b : {Vec3(0.25f, 0.5f, 0.25f), Vec3(0.3f, 0.45f, 0.25f)}) {
    EXPECT_FALSE(mesh.shadingNormal(0, b)) << b.transpose();
  }
  ASSERT_TRUE(mesh.shadingNormal(0, Vec3(0.9f, 0.05f, 0.05f)));
  const Scene scene(mesh);
  const SurfaceHit h = scene.hitFromFace(0, 0.5f, 0.25f);  // b0 = 0.25, b1 = 0.5, b2 = 0.25
  ASSERT_TRUE(h.ns.allFinite());
  EXPECT_TRUE(h.ns.isApprox(h.ng)) << h.ns.transpose();
  // All three normals facing away: a reliable normal on the other side; the renderer's frame is
  // put on the winding side, the authored side is kept by shadingNormal.
  const auto away = mesh.shadingNormal(1, Vec3::Constant(1.0f / 3));
  ASSERT_TRUE(away);
  EXPECT_LT(away->z(), -0.99f);
  EXPECT_GT(scene.hitFromFace(1, 0.3f, 0.3f).ns.z(), 0.99f);
}

// The renderer keeps each face's vertex normals in its face record: a hit's shading normal must be
// exactly the mesh's interpolation of the face's own vertex normals (an index mix-up would pick a
// neighbour's), flipped to the winding side.
TEST(Scene, HitShadingNormalIsTheMeshInterpolation) {
  MeshData d;
  Pcg32 rng(7);
  const int n = 12;  // a height field of (n + 1)^2 vertices, each with its own tilted normal
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x) {
      d.positions.push_back({float(x), float(y), 0.1f * rng.next1D()});
      const Vec3 u = rng.next3D();
      d.normals.push_back(Vec3(u.x() - 0.5f, u.y() - 0.5f, u.z() < 0.2f ? -1.0f : 1.0f).normalized());
    }
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const int v = y * (n + 1) + x;
      d.triangles.push_back({v, v + 1, v + n + 2});
      d.triangles.push_back({v, v + n + 2, v + n + 1});
    }
  const TriangleMesh mesh = buildMesh(d, "tilted normals");
  const Scene scene(mesh);
  size_t smooth = 0;
  for (uint32_t f = 0; f < mesh.triangles.size(); ++f) {
    const float b1 = 0.8f * rng.next1D(), b2 = (0.95f - b1) * rng.next1D();
    const SurfaceHit h = scene.hitFromFace(f, b1, b2);
    const auto expected = mesh.shadingNormal(f, Vec3(1.0f - b1 - b2, b1, b2));
    if (!expected) {
      EXPECT_EQ(h.ns, h.ng);
      continue;
    }
    ++smooth;
    EXPECT_EQ(h.ns, expected->dot(h.ng) >= 0 ? *expected : Vec3(-*expected)) << "face " << f;
  }
  EXPECT_GT(smooth, mesh.triangles.size() / 2);
}

TEST(Scene, TexelNormalsAreFiniteAndCountFallbacks) {
  TriangleMesh mesh = buildAtlas(opposedNormals(), {});
  const TexelMap map(mesh, 256);
  size_t fellBack = 0, valid = 0;
  for (size_t t = 0; t < map.texelCount(); ++t) {
    if (!map.valid(t)) continue;
    ++valid;
    bool geometric = false;
    const Vec3 n = map.normal(mesh, t, &geometric);
    ASSERT_TRUE(n.allFinite());
    ASSERT_NEAR(n.norm(), 1.0f, 1e-4f);
    fellBack += geometric;
    ASSERT_TRUE(map.point(mesh, t).allFinite());
  }
  EXPECT_GT(fellBack, 0u);
  EXPECT_LT(fellBack, valid);
}

TEST(Scene, TexelMapOfADegenerateUvTriangleHasNoNaN) {
  MeshData d;
  d.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  d.uvs = {{0.2f, 0.2f}, {0.6f, 0.6f}, {0.4f, 0.4f}};  // collinear: no uv area
  d.triangles = {{0, 1, 2}};
  const TriangleMesh mesh = buildMesh(d, "flat uv");
  const TexelMap map(mesh, 64);
  size_t valid = 0;
  for (size_t t = 0; t < map.texelCount(); ++t) {
    if (!map.valid(t)) continue;
    ++valid;
    ASSERT_TRUE(map.point(mesh, t).allFinite());
  }
  EXPECT_GT(valid, 0u);
}

#ifdef NDEBUG
TEST(Scene, NonFiniteAndInvertedRaysAreSkippedAndCounted) {
  const Scene scene(opposedNormals());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(scene.occluded(Vec3(nan, 0, 1), Vec3(0, 0, -1), 1.0f));
  EXPECT_TRUE(scene.occluded(Vec3(0.2f, 0.2f, 1), Vec3(0, 0, -1), -1e-4f));  // a point within 2 eps of the camera
  EXPECT_FALSE(scene.intersect(Vec3(0.2f, 0.2f, 1), Vec3(0, nan, -1)));
  EXPECT_EQ(scene.hitDistance(Vec3(0.2f, 0.2f, 1), Vec3(0, 0, -1), nan), INFINITY);
  EXPECT_EQ(scene.skippedRays(), 4u);
  // Valid rays are traced as before.
  EXPECT_TRUE(scene.intersect(Vec3(0.2f, 0.2f, 1), Vec3(0, 0, -1)));
  EXPECT_EQ(scene.skippedRays(), 4u);
}
#else
TEST(Scene, NonFiniteRayAssertsInDebugBuilds) {
  const Scene scene(opposedNormals());
  EXPECT_DEATH(scene.occluded(Vec3(std::numeric_limits<float>::quiet_NaN(), 0, 1), Vec3(0, 0, -1), 1.0f),
               "non-finite or inverted ray");
}
#endif

// An error Embree reports through its callback (here an invalid argument on the scene's own
// device) is kept and fails the command as one relume::Error naming it; the first one wins.
TEST(Scene, AnEmbreeErrorFailsWithItsMessage) {
  const Scene scene(opposedNormals());
  EXPECT_NO_THROW(scene.throwIfEmbreeFailed());
  rtcReleaseGeometry(rtcNewGeometry(scene.embreeDevice(), static_cast<RTCGeometryType>(12345)));
  try {
    scene.throwIfEmbreeFailed();
    ADD_FAILURE() << "the Embree error was not reported";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("embree error"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("2 triangles"), std::string::npos) << e.what();
  }
}
