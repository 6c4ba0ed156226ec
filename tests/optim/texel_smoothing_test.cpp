#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "optim/texel_smoothing.h"

using namespace relume;

namespace {

// Quad A (object 0, the unit square at z = 0, uv [0.05, 0.45] x [0.1, 0.9]) holds an albedo edge
// at x = 0.5: 0.3 left of it, 0.8 right. Quad B (object 0 too) lies 10 m away in 3D but touches A
// in the atlas (uv from 0.45), albedo 0.9: only the surface distance keeps it out of A's texels.
struct TwoQuads {
  TriangleMesh mesh;
  TexelMap map;
  std::vector<float> truth, guide;
  std::vector<uint8_t> eligible;
  std::vector<int> column;  // texel -> x index within A in texels from its left edge (-1: B or none)
  TwoQuads() {
    MeshData d;
    d.positions = {{0, 0, 0}, {1, 0, 0}, {1, 2, 0}, {0, 2, 0}, {10, 0, 0}, {11, 0, 0}, {11, 2, 0}, {10, 2, 0}};
    d.uvs = {{0.05f, 0.1f}, {0.45f, 0.1f}, {0.45f, 0.9f}, {0.05f, 0.9f},
             {0.45f, 0.1f}, {0.85f, 0.1f}, {0.85f, 0.9f}, {0.45f, 0.9f}};
    d.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
    d.faceObject = {0, 0, 0, 0};
    mesh = buildMesh(d, "quads");
    map = TexelMap(mesh, 128);
    const size_t n = map.texelCount();
    truth.assign(3 * n, 0.0f), guide.assign(3 * n, 0.0f), eligible.assign(n, 0), column.assign(n, -1);
    for (size_t t = 0; t < n; ++t) {
      if (!map.covered(t)) continue;
      eligible[t] = 1;
      const Vec3 p = map.point(mesh, t);
      const float a = p.x() > 9 ? 0.9f : p.x() < 0.5f ? 0.3f : 0.8f;
      if (p.x() < 9) column[t] = static_cast<int>(std::floor(p.x() * 51.2f));  // 0.4 x 128 texels per metre
      for (int c = 0; c < 3; ++c) truth[3 * t + c] = a, guide[3 * t + c] = 0.5f * a;  // uniform light
    }
  }
  bool interior(size_t t) const {  // in A, 3+ texels from the edge and A's sides
    const int k = column[t];
    if (k < 0) return false;
    const Vec3 p = map.point(mesh, t);
    return k >= 3 && k <= 47 && std::abs(k - 25.6f) > 3 && p.y() > 0.15f && p.y() < 1.85f;
  }
};

double rms(const std::vector<float>& v, const std::vector<float>& ref, const TwoQuads& q) {
  double s = 0;
  size_t n = 0;
  for (size_t t = 0; t < q.map.texelCount(); ++t)
    if (q.interior(t))
      for (int c = 0; c < 3; ++c) s += std::pow(v[3 * t + c] - ref[3 * t + c], 2), ++n;
  return std::sqrt(s / n);
}

}  // namespace

// Noise of known spread on both sides of an albedo edge: smoothing the ratio to a guide that has
// the edge removes most of it, and the errors it reports are the ones left.
TEST(TexelSmoothing, RemovesNoiseAndReportsWhatIsLeft) {
  const TwoQuads q;
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  std::vector<float> noisy = q.truth, error(q.truth.size(), 0.05f);
  for (float& v : noisy) v += noise(rng);
  for (const bool withGuide : {false, true}) {
    const SmoothedTexels s = smoothTexels(q.map, q.mesh, noisy, error, q.eligible,
                                          withGuide ? std::span<const float>(q.guide) : std::span<const float>{},
                                          {});
    const double before = rms(noisy, q.truth, q), after = rms(s.values, q.truth, q);
    EXPECT_LT(after, before / 2.5) << "guide " << withGuide << ": RMS " << before << " -> " << after;
    double reported = 0;
    size_t n = 0;
    for (size_t t = 0; t < q.map.texelCount(); ++t)
      if (q.interior(t))
        for (int c = 0; c < 3; ++c) reported += std::pow(s.standardError[3 * t + c], 2), ++n;
    reported = std::sqrt(reported / n);
    EXPECT_GT(reported, 0.8 * after) << withGuide;
    EXPECT_LT(reported, 1.25 * after) << withGuide;
    EXPECT_GT(s.smoothed, q.map.coveredCount() * 9 / 10);
  }
}

// Without noise: with the guide, whose edge is where the albedo's is, the edge stays exactly;
// without it, the edge is resolved by the errors and stays too, and texels away from it
// stay exactly, so quad B (0.9, next to A's 0.8 in
// the atlas but 10 m away on the surface) never mixes in. Texels that are not eligible, or whose
// error is unknown, keep what they had.
TEST(TexelSmoothing, KeepsTheGuidesEdgesAndTheSurfacesNeighbourhood) {
  TwoQuads q;
  std::vector<float> error(q.truth.size(), 0.05f);
  size_t skipped = 0, unknown = 0;
  for (size_t t = 0; t < q.map.texelCount(); ++t) {
    if (!q.map.covered(t)) continue;
    if (t % 17 == 0) q.eligible[t] = 0, ++skipped;
    if (t % 19 == 0) error[3 * t] = -1.0f, ++unknown;
  }
  EXPECT_GT(skipped, 0u);
  EXPECT_GT(unknown, 0u);
  std::vector<float> values = q.truth;
  for (size_t t = 0; t < q.map.texelCount(); t += 17) values[3 * t] = 0.0f;  // not eligible: left as it is
  for (const bool withGuide : {false, true}) {
    const SmoothedTexels s = smoothTexels(q.map, q.mesh, values, error, q.eligible,
                                          withGuide ? std::span<const float>(q.guide) : std::span<const float>{},
                                          {});
    size_t nextToB = 0;
    for (size_t t = 0; t < q.map.texelCount(); ++t) {
      if (!q.map.covered(t)) continue;
      const bool nearEdge = q.column[t] >= 0 && std::abs(q.column[t] - 25.6f) <= 3;
      nextToB += q.column[t] >= 49;
      for (int c = 0; c < 3; ++c)
        if (t % 17 == 0 || t % 19 == 0)
          ASSERT_EQ(s.values[3 * t + c], values[3 * t + c]) << t;
        else  // without the guide, the edge (10 standard errors of the difference) is kept out all but
              // a trace
          ASSERT_NEAR(s.values[3 * t + c], q.truth[3 * t + c], withGuide || !nearEdge ? 1e-5f : 5e-3f)
              << t << " column " << q.column[t];
    }
    EXPECT_GT(nextToB, 50u);
  }
}

// An albedo step smaller than the estimate's noise (0.08 against 0.05 per texel) cannot be told
// from it texel by texel, and smoothing by the errors alone spreads it; a guide that shows it
// (the frames' radiance, 2% noise) keeps it, and its own noise stays out of the result.
TEST(TexelSmoothing, EdgesTheGuideShowsAreKeptBelowTheNoise) {
  TwoQuads q;
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (size_t t = 0; t < q.map.texelCount(); ++t) {
    if (!q.map.covered(t)) continue;
    const float a = q.column[t] < 0 ? 0.9f : q.column[t] < 26 ? 0.5f : 0.58f;
    for (int c = 0; c < 3; ++c) q.truth[3 * t + c] = a;
    const float g = 0.5f * a * (1 + 0.02f * noise(rng));
    for (int c = 0; c < 3; ++c) q.guide[3 * t + c] = g;
  }
  std::vector<float> noisy = q.truth, error(q.truth.size(), 0.05f);
  for (float& v : noisy) v += 0.05f * noise(rng);
  // The mean signed error of the columns on either side of the step (over ~100 rows each), and
  // the RMS error in the interior.
  auto measure = [&](const std::vector<float>& v, double& stepBias, double& interior) {
    double sum[2] = {0, 0};
    size_t n[2] = {0, 0};
    for (size_t t = 0; t < q.map.texelCount(); ++t)
      if (q.column[t] == 25 || q.column[t] == 26) {
        const int side = q.column[t] == 26;
        for (int c = 0; c < 3; ++c) sum[side] += v[3 * t + c] - q.truth[3 * t + c], ++n[side];
      }
    stepBias = std::max(std::abs(sum[0] / n[0]), std::abs(sum[1] / n[1]));
    interior = rms(v, q.truth, q);
  };
  double bias[2], interior[2];
  for (const int use : {0, 1}) {
    const SmoothedTexels s = smoothTexels(q.map, q.mesh, noisy, error, q.eligible,
                                          use ? std::span<const float>(q.guide) : std::span<const float>{}, {});
    measure(s.values, bias[use], interior[use]);
  }
  EXPECT_GT(bias[0], 0.01) << "no guide: the step is spread";
  EXPECT_LT(bias[1], 0.005) << "the guide: the step kept";
  EXPECT_LT(interior[1], 1.1 * interior[0]) << "the guide's noise stays out";
}
