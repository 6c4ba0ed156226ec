// The scale of lights seen only saturated, from texel sums whose truth the test sets: each object
// one albedo, its texels lit directly by the clipped lights in different measure.
#include "product/clipped_light_scale.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

using namespace relume;

namespace {

// `objects` objects of `perObject` texels: albedo a_o; light c reaches a texel with a direct share
// that varies over the object (light 1 from the other end of the room than light 0). What the frames show is a_o (sum_c
// s_c D_c + R) times log-normal noise of `noise`; the paths are exact (no covariance).
std::vector<ScaleTexel> texels(const std::vector<double>& truth, int objects, int perObject, double noise,
                               uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> n(0, 1);
  const size_t K = truth.size();
  std::vector<ScaleTexel> out;
  for (int o = 0; o < objects; ++o) {
    const double albedo = 0.2 + 0.6 * u(rng);
    for (int k = 0; k < perObject; ++k) {
      ScaleTexel t;
      t.object = o;
      const double x = u(rng);  // where the texel lies between the two ends
      for (size_t c = 0; c < K; ++c) t.mean.push_back((c % 2 == 0 ? x : 1 - x) * u(rng));
      t.mean.push_back(0.05 + 0.3 * u(rng));
      double lit = t.mean[K];
      for (size_t c = 0; c < K; ++c) lit += truth[c] * t.mean[c];
      t.shown = albedo * lit * std::exp(noise * n(rng));
      t.covariance.assign((K + 1) * (K + 1), 0.0);
      out.push_back(t);
    }
  }
  return out;
}

}  // namespace

TEST(ClippedLightScale, TheUniformAlbedoScaleIsFound) {
  for (double truth : {0.5, 1.0, 1.6, 3.0}) {
    const ScaleFit exact = fitClippedScales(texels({truth}, 6, 200, 0.01, 1), 32, 0.1);
    EXPECT_NEAR(exact.scale[0] / truth, 1.0, 0.02) << truth;
    EXPECT_LT(exact.logError[0], 0.02) << truth;
    const ScaleFit noisy = fitClippedScales(texels({truth}, 6, 200, 0.1, 2), 32, 0.1);
    EXPECT_NEAR(noisy.scale[0] / truth, 1.0, 0.08) << truth;
    EXPECT_LT(noisy.logError[0], 0.1) << truth;
    EXPECT_EQ(noisy.objects, 6);
    EXPECT_EQ(noisy.texels, 1200u);
  }
}

// Two lights lighting the room from its two ends: each gets its own scale.
TEST(ClippedLightScale, LightsThatLightDifferentPlacesGetTheirOwn) {
  const ScaleFit fit = fitClippedScales(texels({1.7, 1.3}, 8, 300, 0.02, 7), 32, 0.1);
  EXPECT_FALSE(fit.common);
  EXPECT_NEAR(fit.scale[0] / 1.7, 1.0, 0.04);
  EXPECT_NEAR(fit.scale[1] / 1.3, 1.0, 0.04);
}

// The lights' errors when each has its own scale are the jackknife over objects: each object left
// out and the scales fitted again. Here each object's albedo also trends with the two lights'
// direct shares, so the objects disagree on the scales by more than their texels' noise, and the
// jackknife, not the curvature, sets the error. Fitted from scratch without each object (the
// grouping given), the left-out scales give the errors the fit states.
TEST(ClippedLightScale, TheErrorIsTheJackknifeOverObjectsFittedAgain) {
  std::vector<ScaleTexel> all = texels({1.7, 1.3}, 8, 300, 0.02, 7);
  std::mt19937 rng(17);
  std::normal_distribution<double> n(0, 1);
  std::vector<double> trend(8);
  for (double& b : trend) b = 0.3 * n(rng);
  for (ScaleTexel& t : all) t.shown *= std::exp(trend[t.object] * (t.mean[0] - t.mean[1]));
  const ScaleFit fit = fitClippedScales(all, 32, 0.1);
  ASSERT_FALSE(fit.common);
  std::vector<std::vector<double>> leftOut(2);
  for (int o = 0; o < 8; ++o) {
    std::vector<ScaleTexel> rest;
    for (const ScaleTexel& t : all)
      if (t.object != o) rest.push_back(t);
    const ScaleFit without = fitClippedScales(rest, 32, 0.1, fit.groupOf);
    for (int c = 0; c < 2; ++c) leftOut[c].push_back(std::log(without.scale[c]));
  }
  for (int c = 0; c < 2; ++c) {
    double mean = 0, squares = 0;
    for (double x : leftOut[c]) mean += x / 8;
    for (double x : leftOut[c]) squares += (x - mean) * (x - mean);
    const double jackknife = std::sqrt(7.0 / 8.0 * squares);
    EXPECT_GT(jackknife, 0.01) << c;  // well above the texels' noise
    EXPECT_NEAR(fit.logError[c] / jackknife, 1.0, 1e-3) << c;
  }
}

// Two lights whose light falls everywhere in the same proportion: only their common scale is known.
TEST(ClippedLightScale, LightsNoSurfaceTellsApartShareOneScale) {
  std::vector<ScaleTexel> same = texels({1.5}, 6, 200, 0.02, 8);
  for (ScaleTexel& t : same) {  // light 0 gives two thirds of the direct light everywhere, light 1 a third
    t.mean = {2 * t.mean[0] / 3, t.mean[0] / 3, t.mean[1]};
    t.covariance.assign(9, 0.0);
  }
  const ScaleFit fit = fitClippedScales(same, 32, 0.1);
  EXPECT_TRUE(fit.common);
  EXPECT_NEAR(fit.scale[0] / 1.5, 1.0, 0.04);
  EXPECT_EQ(fit.scale[0], fit.scale[1]);
}

// Two lights whose light falls everywhere in the same proportion (two windows in one wall), and a
// third from the other end of the room, 3x brighter than its floor where they are 1.2x (a pendant
// lamp): the two share one scale, the third keeps its own. With only "each its own or one for
// all", the pair's unknown split would put all three under one scale.
TEST(ClippedLightScale, LightsNoSurfaceTellsApartShareAGroupAndTheRestKeepTheirOwn) {
  std::vector<ScaleTexel> three = texels({1.2, 3.0}, 8, 300, 0.02, 14);
  for (ScaleTexel& t : three) {
    t.mean = {2 * t.mean[0] / 3, t.mean[0] / 3, t.mean[1], t.mean[2]};
    t.covariance.assign(16, 0.0);
  }
  const ScaleFit fit = fitClippedScales(three, 32, 0.1);
  EXPECT_FALSE(fit.common);
  ASSERT_EQ(fit.groupOf.size(), 3u);
  EXPECT_EQ(fit.groupOf[0], fit.groupOf[1]);
  EXPECT_NE(fit.groupOf[0], fit.groupOf[2]);
  EXPECT_EQ(fit.scale[0], fit.scale[1]);
  EXPECT_NEAR(fit.scale[0] / 1.2, 1.0, 0.04);
  EXPECT_NEAR(fit.scale[2] / 3.0, 1.0, 0.04);
  EXPECT_LT(fit.logError[2], 0.05);
  // A channel's fit takes the grouping it is given.
  const ScaleFit given = fitClippedScales(three, 32, 0.1, {0, 1, 1});
  EXPECT_EQ(given.groupOf, (std::vector<int>{0, 1, 1}));
  EXPECT_EQ(given.scale[1], given.scale[2]);
}

// The paths' noise in D and R, left in the spread, pulls the scale up: taken out, the scale is
// that of exact paths.
TEST(ClippedLightScale, PathNoiseDoesNotPullTheScale) {
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0, 1);
  std::vector<ScaleTexel> noisy = texels({1.5}, 8, 300, 0.02, 9);
  const double paths = 32;  // 4 frames x 8 paths
  for (ScaleTexel& t : noisy) {
    const double sdD = 0.1 * t.mean[0], sdR = 1.5 * t.mean[1];  // per path: a light sampled, the rest traced
    t.mean[0] = std::max(0.0, t.mean[0] + sdD / std::sqrt(paths) * n(rng));
    t.mean[1] = std::max(1e-3, t.mean[1] + sdR / std::sqrt(paths) * n(rng));
    t.covariance = {sdD * sdD / paths, 0, 0, sdR * sdR / paths};
  }
  std::vector<ScaleTexel> ignored = noisy;
  for (ScaleTexel& t : ignored) t.covariance.assign(4, 0.0);
  const double corrected = fitClippedScales(noisy, 32, 0.1).scale[0];
  const double uncorrected = fitClippedScales(ignored, 32, 0.1).scale[0];
  EXPECT_NEAR(corrected / 1.5, 1.0, 0.015);
  EXPECT_GT(uncorrected / 1.5, 1.03);
  std::printf("ClippedLightScale noise: scale %.3f with the noise taken out, %.3f left in (truth 1.5)\n", corrected,
              uncorrected);
}

// Lit alike everywhere (the same direct share at every texel), a surface's albedo is uniform at
// any scale: nothing is known, and the error says so.
TEST(ClippedLightScale, NoContrastInTheDirectLightIsNoEvidence) {
  std::vector<ScaleTexel> flat = texels({2.0}, 5, 100, 0.05, 3);
  for (ScaleTexel& t : flat) {
    const double a = t.shown / (2.0 * t.mean[0] + t.mean[1]);
    t.mean = {0.5, 0.2}, t.shown = a * (2.0 * 0.5 + 0.2);
  }
  EXPECT_FALSE(std::isfinite(fitClippedScales(flat, 32, 0.1).logError[0]));
}

// The fit asks for another probe after a scale that moved some light by more than its error:
// a scale of 1.6 known to 1% moves it; one of 1 (the albedo already agrees with the lights as
// they are) does not, nor does any scale whose error is unknown.
TEST(ClippedLightScale, OnlyAScaleBeyondItsErrorMovesTheLights) {
  const ScaleFit moved = fitClippedScales(texels({1.6}, 6, 200, 0.01, 1), 32, 0.1);
  EXPECT_TRUE(moved.movesLights());
  EXPECT_TRUE(moved.known(0.1));
  const ScaleFit settled = fitClippedScales(texels({1.0}, 6, 200, 0.01, 1), 32, 0.1);
  EXPECT_GT(settled.logError[0], std::abs(std::log(settled.scale[0])));
  EXPECT_FALSE(settled.movesLights());
  EXPECT_TRUE(settled.known(0.1));
  const ScaleFit unknown = fitClippedScales(texels({1.6}, 2, 200, 0.01, 4), 32, 0.1);
  EXPECT_FALSE(unknown.movesLights());
  EXPECT_FALSE(unknown.known(0.1));
  // One light moved among several is enough; a second that stays does not cancel it.
  const ScaleFit two = fitClippedScales(texels({1.0, 1.5}, 8, 300, 0.02, 7), 32, 0.1);
  ASSERT_FALSE(two.common);
  EXPECT_TRUE(two.movesLights());
}

TEST(ClippedLightScale, TooFewObjectsOrTexelsGiveNoError) {
  EXPECT_FALSE(std::isfinite(fitClippedScales(texels({1.5}, 2, 200, 0.01, 4), 32, 0.1).logError[0]));
  const ScaleFit few = fitClippedScales(texels({1.5}, 6, 20, 0.01, 5), 32, 0.1);
  EXPECT_EQ(few.objects, 0);
  EXPECT_FALSE(std::isfinite(few.logError[0]));
  EXPECT_TRUE(fitClippedScales({}, 32, 0.1).scale.empty());
}

// Beyond the searched range the minimum is on its edge: not taken for an answer.
TEST(ClippedLightScale, AScaleBeyondTheRangeIsNotTakenForOne) {
  EXPECT_FALSE(std::isfinite(fitClippedScales(texels({40.0}, 6, 200, 0.01, 6), 32, 0.1).logError[0]));
}

// A texel's highlight (what its specular lobe returns, G) is radiance its albedo does not scale;
// where the clipped light reaches it directly, it is brightest. Counted as diffuse, it makes the
// directly lit texels look lighter and pulls the scale; given apart, it is taken out exactly.
TEST(ClippedLightScale, AHighlightTheAlbedoDoesNotScaleIsTakenOut) {
  const double truth = 1.6;
  std::vector<ScaleTexel> glossy = texels({truth}, 6, 200, 0.01, 11);
  for (ScaleTexel& t : glossy) {
    t.specular = {0.08 * t.mean[0], 0.02 * t.mean[1]};  // a dielectric's lobe, sharper toward the light
    t.shown += truth * t.specular[0] + t.specular[1];
    t.covariance.assign(16, 0.0);
  }
  std::vector<ScaleTexel> asDiffuse = glossy;
  for (ScaleTexel& t : asDiffuse) t.specular.clear(), t.covariance.assign(4, 0.0);
  const double apart = fitClippedScales(glossy, 32, 0.1).scale[0];
  const double diffuse = fitClippedScales(asDiffuse, 32, 0.1).scale[0];
  EXPECT_NEAR(apart / truth, 1.0, 0.02);
  EXPECT_GT(std::abs(diffuse / truth - 1.0), 0.04);
  std::printf("ClippedLightScale highlight: scale %.3f with the lobe apart, %.3f counted as diffuse (truth %.1f)\n",
              apart, diffuse, truth);
}

// Traced under the wrong material, an object's direct share is wrong by a factor that varies
// over it (a grazing light), and its albedo cannot be uniform at any scale; under its own it can.
// Each object keeps the set its albedo is most uniform under.
TEST(ClippedLightScale, EachObjectKeepsTheMaterialItsAlbedoIsMostUniformUnder) {
  const std::vector<ScaleTexel> exact = texels({1.4}, 4, 200, 0.02, 12);
  std::vector<ScaleTexel> wrong = exact;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(0.5, 1.5);
  for (ScaleTexel& t : wrong) t.mean[0] *= u(rng);
  // Objects 0 and 1 were made with the first set's terms, 2 and 3 with the second's: swap theirs.
  std::vector<ScaleTexel> first = exact, second = wrong;
  for (size_t i = 0; i < first.size(); ++i)
    if (first[i].object >= 2) std::swap(first[i], second[i]);
  EXPECT_EQ(chooseFirstVertexMaterials({first, second}, 4, 32, {1.4}), (std::vector<int>{0, 0, 1, 1}));
  EXPECT_EQ(chooseFirstVertexMaterials({second, first}, 4, 32, {1.4}), (std::vector<int>{1, 1, 0, 0}));
  // Too few texels: the fit's own (0).
  EXPECT_EQ(chooseFirstVertexMaterials({first, second}, 4, 1000, {1.4}), (std::vector<int>{0, 0, 0, 0}));
}

// A material is judged at the scale the objects share, not at the object's own: object 2's second
// set of terms makes its albedo exactly uniform at scale 0.5 (as a glossy lobe can, explaining the
// directly lit texels' excess as a highlight), while every object, object 2 included, is uniform
// up to its noise at 1.4 under the first. Each at its own best scale, object 2 would take the second set.
TEST(ClippedLightScale, AMaterialIsJudgedAtTheScaleTheObjectsShare) {
  const std::vector<ScaleTexel> exact = texels({1.4}, 4, 200, 0.05, 21);
  std::vector<ScaleTexel> second = exact;
  for (ScaleTexel& t : second)
    if (t.object == 2) {
      const double m = t.shown / (0.3 * (0.5 * t.mean[0] + t.mean[1]));
      t.mean[0] *= m, t.mean[1] *= m;
    }
  EXPECT_EQ(chooseFirstVertexMaterials({exact, second}, 4, 32, {1.4}), (std::vector<int>{0, 0, 0, 0}));
  EXPECT_EQ(chooseFirstVertexMaterials({exact, second}, 4, 32, {0.5}), (std::vector<int>{0, 0, 1, 0}));
  // The texels each object's choice holds: object 2's from the second set, the rest from the first.
  std::vector<std::vector<double>> expected, got;
  for (size_t i = 0; i < exact.size(); ++i) expected.push_back((exact[i].object == 2 ? second : exact)[i].mean);
  for (const ScaleTexel& t : chosenTexels({exact, second}, {0, 0, 1, 0})) got.push_back(t.mean);
  std::sort(expected.begin(), expected.end()), std::sort(got.begin(), got.end());
  EXPECT_EQ(got, expected);
}

namespace {

// The texels of `texels` with object o's albedo set to `albedo` (what the frames show of it scaled).
std::vector<ScaleTexel> withAlbedo(std::vector<ScaleTexel> all, const std::vector<double>& truth, int o,
                                   double albedo) {
  for (ScaleTexel& t : all) {
    if (t.object != o) continue;
    double lit = t.mean.back();
    for (size_t c = 0; c < truth.size(); ++c) lit += truth[c] * t.mean[c];
    t.shown = albedo * lit;
  }
  return all;
}

}  // namespace

// With the lights 1.8x too dark, an object of albedo 1 needs them exactly 1.8x brighter, and one of
// albedo 0.95 (white paint) a little less, its light from the rest of the room (R) not scaled: the
// ceiling is a lower bound, set by the whitest object. At the true scale, no object exceeds 1.
TEST(ClippedLightScale, TheAlbedoCeilingBoundsTheLightsFromBelow) {
  const std::vector<double> truth = {1.8};
  const std::vector<ScaleTexel> room = texels(truth, 6, 200, 0.0, 31);  // albedo in [0.2, 0.8]
  const AlbedoCeiling white = albedoCeiling(withAlbedo(room, truth, 3, 1.0), 32, {1.0}, 3.0);
  EXPECT_EQ(white.object, 3);
  EXPECT_NEAR(white.factor, 1.8, 1e-6);  // noise-free: no error to take off
  EXPECT_EQ(white.perObject.size(), 6u);
  const AlbedoCeiling paint = albedoCeiling(withAlbedo(room, truth, 3, 0.95), 32, {1.0}, 3.0);
  EXPECT_EQ(paint.object, 3);
  EXPECT_LT(paint.factor, 0.95 * 1.8);
  EXPECT_GT(paint.factor, 0.85 * 1.8);
  // The bound does not depend on the scales it starts from: from the lights at 1.2, the factor left is 1.5.
  EXPECT_NEAR(albedoCeiling(withAlbedo(room, truth, 3, 1.0), 32, {1.2}, 3.0).factor, 1.5, 1e-6);
  // At the true scale every albedo is at most 1: no factor, no object.
  const AlbedoCeiling atTruth = albedoCeiling(withAlbedo(room, truth, 3, 1.0), 32, truth, 3.0);
  EXPECT_EQ(atTruth.factor, 1.0);
  EXPECT_EQ(atTruth.object, -1);
  // Too few texels: the object does not count.
  EXPECT_EQ(albedoCeiling(withAlbedo(room, truth, 3, 1.0), 1000, {1.0}, 3.0).object, -1);
}

// The frames' noise widens each object's bound by its standard error, and the ceiling takes
// `sigmas` of it off: over seeds, an albedo-1 object's noisy bound stays below the truth, and its
// error is the spread of the bound over those seeds.
TEST(ClippedLightScale, TheAlbedoCeilingTakesItsNoiseOff) {
  const std::vector<double> truth = {1.8};
  std::vector<double> factors, errors;
  for (uint32_t seed = 40; seed < 80; ++seed) {
    std::vector<ScaleTexel> room = withAlbedo(texels(truth, 6, 200, 0.0, seed), truth, 3, 1.0);
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0, 1);
    for (ScaleTexel& t : room) t.shown *= 1 + 0.1 * n(rng);
    const AlbedoCeiling c = albedoCeiling(room, 32, {1.0}, 3.0);
    EXPECT_LT(c.factor, 1.8) << seed;
    const auto own = std::find_if(c.perObject.begin(), c.perObject.end(), [](const auto& b) { return b.object == 3; });
    ASSERT_NE(own, c.perObject.end());
    factors.push_back(own->factor), errors.push_back(own->error);
  }
  double mean = 0, squares = 0;
  for (double f : factors) mean += f / factors.size();
  for (double f : factors) squares += (f - mean) * (f - mean) / (factors.size() - 1);
  const double meanError = std::accumulate(errors.begin(), errors.end(), 0.0) / errors.size();
  EXPECT_NEAR(mean, 1.8, 3 * std::sqrt(squares / factors.size()));
  EXPECT_NEAR(meanError / std::sqrt(squares), 1.0, 0.3);
}
