// Peers' truth measures of `relume eval`: 8-bit albedo and roughness map PSNR, emission IoU.
#include <gtest/gtest.h>

#include <cmath>

#include "product/evaluate.h"
#include "scenes/synth.h"

using namespace relume;

namespace {
struct Pair {
  SceneDescription truth, fit;
  Image coverage;  // every texel observed 10 times
};
Pair roomPair() {
  Pair p{makeSynthScene(SynthSceneKind::Room, 64).scene, makeSynthScene(SynthSceneKind::Room, 64).scene, Image(64, 64)};
  std::fill(p.coverage.rgb.begin(), p.coverage.rgb.end(), 10.0f);
  return p;
}
int idOf(const Appearance& a, const std::string& name) {
  return static_cast<int>(std::find(a.names.begin(), a.names.end(), name) - a.names.begin());
}
}  // namespace

TEST(Evaluate, PeersMeasuresAreExactOnTheTruthAndFallWithErrors) {
  Pair p = roomPair();
  const TruthComparison same = compareWithTruth(p.fit, p.truth, p.coverage, {});
  EXPECT_GT(same.albedoTexels, 500u);
  EXPECT_NEAR(same.albedoPsnr8, 120.0, 1e-9);  // identical maps: the 1e-12 floor of the MSE
  EXPECT_NEAR(same.roughnessPsnr8, 120.0, 1e-9);
  EXPECT_DOUBLE_EQ(same.emissionIou, 1.0);

  // Every roughness off by 0.2 (= 51 steps of 8 bits): PSNR 20 log10(255 / 51) on every texel.
  Appearance& a = p.fit.appearance;
  for (float& r : a.roughness) r = r <= 0.8f ? r + 0.2f : r - 0.2f;
  // Darker albedo everywhere: 8-bit PSNR drops far below the identical maps'.
  for (float& v : a.albedo.rgb) v *= 0.5f;
  // One of the two ceiling lights off: the emitting texels of the other are the intersection.
  a.emission[idOf(a, "ceiling_light_b")] = Color::Zero();
  const TruthComparison off = compareWithTruth(p.fit, p.truth, p.coverage, {});
  EXPECT_NEAR(off.roughnessPsnr8, 20.0 * std::log10(255.0 / 51.0), 1e-6);
  EXPECT_LT(off.albedoPsnr8, 25.0);
  EXPECT_GT(off.emissionIou, 0.2);
  EXPECT_LT(off.emissionIou, 0.8);
}
