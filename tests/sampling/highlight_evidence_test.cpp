#include <gtest/gtest.h>

#include <random>

#include "core/error.h"
#include "sampling/highlight_evidence.h"

using namespace relume;

namespace {
// `texels` slots of object `o`, each with one ray seeing a light (radiance x (1 + contrast)) and
// two not, the base radiance varying per texel (albedo, irradiance) and 10% pixel noise.
struct Rays {
  std::vector<uint32_t> slot;
  std::vector<int> object;
  std::vector<float> luminance;
  std::vector<int8_t> sawLight;
  void add(int o, int texels, double contrast, std::mt19937& rng) {
    std::uniform_real_distribution<double> base(0.05, 2.0);
    std::normal_distribution<double> noise(1.0, 0.1);
    for (int t = 0; t < texels; ++t) {
      const uint32_t s = slot.empty() ? 0 : slot.back() + 1;
      const double b = base(rng);
      for (int k = 0; k < 3; ++k) {
        slot.push_back(s), object.push_back(o), sawLight.push_back(k == 0);
        luminance.push_back(static_cast<float>(b * (k == 0 ? 1 + contrast : 1) * noise(rng)));
      }
    }
  }
};
}  // namespace

TEST(HighlightEvidence, SeesAGlossyObjectAndNotARoughOne) {
  std::mt19937 rng(3);
  Rays r;
  r.add(0, 30, 0.5, rng);      // glossy: 50% brighter with a light reflected, 30 texels
  r.add(1, 2000, 0.005, rng);  // rough wall: 0.5%, many texels
  r.add(2, 5, 3.0, rng);       // a bright highlight on too few texels
  HighlightEvidence e(4);
  e.addBatch(r.slot, r.object, r.luminance, r.sawLight);
  EXPECT_EQ(e.texels(0), 30u);
  EXPECT_NEAR(e.contrast(0), 0.5, 0.1);
  EXPECT_NEAR(e.contrast(1), 0.005, 0.01);
  EXPECT_GT(e.standardError(1), 0.0);
  EXPECT_LT(e.standardError(1), e.standardError(0));
  EXPECT_TRUE(e.observed(0, 8, 0.1));
  EXPECT_FALSE(e.observed(1, 8, 0.1));
  EXPECT_FALSE(e.observed(2, 8, 0.1));
  EXPECT_TRUE(e.observed(2, 4, 0.1));
  EXPECT_FALSE(e.observed(3, 1, -1.0));  // never seen
}

TEST(HighlightEvidence, OnlyTexelsSeenBothWaysCountAndBadRaysAreSkipped) {
  // Slot 0: only with a light; slot 1: only without; slot 2: both, one ray masked (-1) and one
  // non-finite; slot 3: both, but the without-light radiance is 0 (no ratio).
  const std::vector<uint32_t> slot = {0, 0, 1, 1, 2, 2, 2, 2, 3, 3};
  const std::vector<int> object = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  const std::vector<float> lum = {5, 6, 1, 1, 3, 1, 100, 1, 2, 0};
  const std::vector<int8_t> saw = {1, 1, 0, 0, 1, 0, -1, 0, 1, 0};
  HighlightEvidence e(1);
  e.addBatch(slot, object, lum, saw);
  EXPECT_EQ(e.texels(0), 1u);
  EXPECT_DOUBLE_EQ(e.contrast(0), 2.0);  // 3 / 1 - 1
  EXPECT_THROW(e.addBatch(slot, object, lum, std::vector<int8_t>(3, 0)), Error);
}

// A rough wall: +0.5% +- 0.3% brighter with a light reflected. Rendered, a lobe of roughness 0.1
// to 0.5 would have made it 40% to 4% brighter; from 0.6 on the difference is within two standard
// errors: roughness at least 0.6, taken as 0.8.
TEST(RoughnessFromAbsence, RulesOutTheRoughnessesThatWouldHaveShownAHighlight) {
  const std::vector<float> grid = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.7f, 0.8f, 0.9f, 1.0f};
  const std::vector<double> rendered = {0.40, 0.25, 0.12, 0.07, 0.04, 0.012, 0.008, 0.006, 0.005, 0.004};
  const std::vector<double> error(grid.size(), 0.002);
  const RoughnessFromAbsence r = roughnessFromAbsence(0.005, 0.003, grid, rendered, error);
  EXPECT_FLOAT_EQ(r.atLeast, 0.6f);
  EXPECT_FLOAT_EQ(r.chosen, 0.8f);
  EXPECT_FALSE(r.roughestRuledOut);
  EXPECT_FALSE(r.sharpBranch());  // the sharpest is ruled out too
  // Noisier frames (+-2%) no longer rule out 0.5: 0.04 - 0.005 is within 2 x 0.0201.
  const RoughnessFromAbsence noisy = roughnessFromAbsence(0.005, 0.02, grid, rendered, error);
  EXPECT_FLOAT_EQ(noisy.atLeast, 0.5f);
  // Nothing seen at all would be consistent with any roughness: the middle of the whole range.
  const RoughnessFromAbsence blind = roughnessFromAbsence(0.005, 1.0, grid, rendered, error);
  EXPECT_FLOAT_EQ(blind.atLeast, 0.1f);
  EXPECT_FLOAT_EQ(blind.chosen, 0.55f);
  EXPECT_FALSE(blind.sharpBranch());
}

// The bound is the interval that reaches 1; a roughness allowed below one that is ruled out is the
// sharp branch (a lobe that never pointed at a light).
TEST(RoughnessFromAbsence, KeepsTheIntervalThatReachesTheRoughestAndASharpBranch) {
  const std::vector<float> grid = {0.25f, 0.5f, 0.75f, 1.0f};
  const std::vector<double> rendered = {0.0, 0.3, 0.0, 0.0};  // 0.25 allowed, 0.5 not
  const std::vector<double> error(grid.size(), 0.01);
  const RoughnessFromAbsence branches = roughnessFromAbsence(0.0, 0.01, grid, rendered, error);
  EXPECT_FLOAT_EQ(branches.atLeast, 0.75f);
  EXPECT_FLOAT_EQ(branches.chosen, 0.875f);
  ASSERT_TRUE(branches.sharpBranch());
  EXPECT_FLOAT_EQ(branches.sharpBelow, 0.375f);
  // Two ruled-out runs: the sharp branch ends at the smoothest ruled out.
  const std::vector<float> fine = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 1.0f};
  const std::vector<double> islands = {0.0, 0.3, 0.0, 0.3, 0.0, 0.0};
  const RoughnessFromAbsence r2 = roughnessFromAbsence(0.0, 0.01, fine, islands, std::vector<double>(6, 0.01));
  EXPECT_FLOAT_EQ(r2.atLeast, 0.5f);
  EXPECT_FLOAT_EQ(r2.sharpBelow, 0.15f);
  // Even the roughest renders more than the frames show: taken as the roughest.
  const std::vector<double> bright(grid.size(), 0.5);
  const RoughnessFromAbsence r = roughnessFromAbsence(0.0, 0.01, grid, bright, error);
  EXPECT_TRUE(r.roughestRuledOut);
  EXPECT_FLOAT_EQ(r.chosen, 1.0f);
  // A texel darker with a light reflected is no evidence against a lobe: -30% counts as 0.
  const std::vector<double> faint = {0.2, 0.02, 0.01, 0.0};
  EXPECT_FLOAT_EQ(roughnessFromAbsence(-0.3, 0.01, grid, faint, error).atLeast, 0.5f);
}
