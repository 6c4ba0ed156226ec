// core/math.h's geometric helpers against brute force.
#include "core/math.h"

#include <gtest/gtest.h>

#include "core/rng.h"

using namespace relume;

// The closest point lies on the triangle and no sampled point of the triangle is nearer.
TEST(ClosestPointOnTriangle, NoPointOfTheTriangleIsNearer) {
  Pcg32 rng(7);
  auto point = [&] { return Vec3(4 * rng.next1D() - 2, 4 * rng.next1D() - 2, 4 * rng.next1D() - 2); };
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 a = point(), b = point(), c = point(), p = point();
    const Vec3 q = closestPointOnTriangle(p, a, b, c);
    // On the triangle: in its plane, with barycentric coordinates in [0, 1].
    const Vec3 n = (b - a).cross(c - a);
    ASSERT_NEAR(n.normalized().dot(q - a), 0.0f, 1e-4f);
    const float area = n.norm();
    const float u = (c - b).cross(q - b).dot(n) / (area * area), v = (a - c).cross(q - c).dot(n) / (area * area);
    EXPECT_GE(u, -1e-4f);
    EXPECT_GE(v, -1e-4f);
    EXPECT_GE(1 - u - v, -1e-4f);
    float nearest = INFINITY;
    for (int i = 0; i <= 60; ++i)
      for (int j = 0; i + j <= 60; ++j)
        nearest = std::min(nearest, (p - (a + (b - a) * (i / 60.0f) + (c - a) * (j / 60.0f))).norm());
    EXPECT_LE((p - q).norm(), nearest + 1e-4f) << trial;
    EXPECT_GT((p - q).norm(), nearest - 0.05f * (b - a).norm() - 0.05f * (c - a).norm()) << trial;
  }
  // Each region: a corner, an edge, the face.
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_TRUE(closestPointOnTriangle(Vec3(-1, -1, 0), a, b, c).isApprox(a));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(0.5f, -1, 2), a, b, c).isApprox(Vec3(0.5f, 0, 0)));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(1, 1, 0), a, b, c).isApprox(Vec3(0.5f, 0.5f, 0)));
  EXPECT_TRUE(closestPointOnTriangle(Vec3(0.2f, 0.3f, -3), a, b, c).isApprox(Vec3(0.2f, 0.3f, 0)));
}
