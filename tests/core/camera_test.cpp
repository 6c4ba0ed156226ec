#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/alias_table.h"
#include "core/error.h"
#include "core/camera.h"
#include "core/rng.h"

using namespace relume;

TEST(Camera, ProjectUnprojectRoundTripWithDistortion) {
  Camera c;
  c.width = 640, c.height = 480;
  c.fx = 500, c.fy = 510, c.cx = 322, c.cy = 238;
  c.distortion = {-0.28f, 0.09f, 0.001f, -0.0015f, -0.01f};
  c.rotation = Eigen::AngleAxisf(0.4f, Vec3(0.2f, 1, 0.1f).normalized()).toRotationMatrix();
  c.position = Vec3(1, 2, 3);
  Pcg32 rng(1);
  for (int i = 0; i < 1000; ++i) {
    const Vec2 u = rng.next2D();
    const Vec2 pixel(u.x() * c.width, u.y() * c.height);
    const auto dir = c.rayDirection(pixel);
    ASSERT_TRUE(dir);
    const auto back = c.project(c.position + 3.7f * *dir);
    ASSERT_TRUE(back);
    EXPECT_NEAR((*back - pixel).norm(), 0.0f, 2e-3f);
  }
  // Distortion really is applied: the corner moves by many pixels.
  Camera pinhole = c;
  pinhole.distortion = {};
  const Vec3 p = c.position + c.rotation * Vec3(0.5f, 0.4f, 1.0f);
  EXPECT_GT((*c.project(p) - *pinhole.project(p)).norm(), 5.0f);
}

TEST(Camera, BehindCameraDoesNotProject) {
  Camera c;
  c.width = c.height = 10;
  EXPECT_FALSE(c.project(Vec3(0, 0, -1)));
}

TEST(AliasTable, MatchesWeights) {
  AliasTable t({1.0, 0.0, 3.0, 6.0});
  EXPECT_FLOAT_EQ(t.pmf(2), 0.3f);
  std::vector<int> counts(4, 0);
  Pcg32 rng(2);
  for (int i = 0; i < 100000; ++i) ++counts[t.sample(rng.next1D())];
  EXPECT_EQ(counts[1], 0);
  EXPECT_NEAR(counts[3] / 100000.0, 0.6, 0.01);
  EXPECT_NEAR(counts[0] / 100000.0, 0.1, 0.01);
}

TEST(AliasTable, RejectsZeroNegativeAndNonFiniteWeights) {
  const auto errorOf = [](const std::vector<double>& w) -> std::string {
    try {
      AliasTable t(w);
    } catch (const Error& e) {
      return e.what();
    }
    return "<no error>";
  };
  EXPECT_NE(errorOf({0.0, 0.0}).find("sum to 0 (must be finite and > 0)"), std::string::npos) << errorOf({0.0, 0.0});
  EXPECT_NE(errorOf({}).find("sum to 0"), std::string::npos);
  EXPECT_NE(errorOf({1.0, 1e308, 1e308}).find("sum to inf"), std::string::npos);
  EXPECT_NE(errorOf({1.0, std::numeric_limits<double>::infinity()}).find("weight 1 is inf"), std::string::npos);
  EXPECT_NE(errorOf({std::nan("")}).find("weight 0 is nan"), std::string::npos);
  EXPECT_NE(errorOf({1.0, -2.0}).find("weight 1 is -2"), std::string::npos);
}

TEST(Rng, SeedsAreIndependentOfOrder) {
  Pcg32 a(hashTuple({1, 2, 3})), b(hashTuple({1, 2, 3})), c(hashTuple({1, 3, 2}));
  EXPECT_EQ(a.nextU32(), b.nextU32());
  EXPECT_NE(Pcg32(hashTuple({1, 2, 3})).nextU32(), c.nextU32());
  float mx = 0;
  for (int i = 0; i < 100000; ++i) mx = std::max(mx, a.next1D());
  EXPECT_LT(mx, 1.0f);
}

// Every stream relume has written (captures, fits, documented figures) drew a point's coordinates last
// first; the order is now explicit and must not change.
TEST(Rng, PointsDrawTheirLastCoordinateFirst) {
  Pcg32 a(5), b(5);
  const float y = b.next1D(), x = b.next1D();
  EXPECT_EQ(a.next2D(), Vec2(x, y));
  const float z3 = b.next1D(), y3 = b.next1D(), x3 = b.next1D();
  EXPECT_EQ(a.next3D(), Vec3(x3, y3, z3));
  EXPECT_EQ(a.nextU32(), b.nextU32());
}
