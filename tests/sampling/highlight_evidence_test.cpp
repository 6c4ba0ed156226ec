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
