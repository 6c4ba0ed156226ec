// Known answer: the built-in room fitted on a short schedule, so that each texel's albedo carries
// the noise of a few visits. The standard errors the fit writes account for that noise, and the
// albedo smoothed by them is nearer the truth than the one left as fitted.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "io/image.h"
#include "io/json.h"
#include "product/evaluate.h"
#include "product/fit.h"
#include "support/prepared_capture.h"
#include "support/small_fit_config.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {
// The result's confidence texture carries each texel's largest standard error, and its evidence
// shares cover every texel.
void expectConfidenceCarriesTheStandardErrors(const fs::path& result) {
  const Image error = readImage(result / "albedo_stderr.exr"), confidence = readImage(result / "confidence.exr");
  ASSERT_EQ(error.width, confidence.width);
  for (size_t t = 0; t < error.rgb.size() / 3; ++t)
    ASSERT_EQ(confidence.rgb[3 * t + 1], std::max({error.rgb[3 * t], error.rgb[3 * t + 1], error.rgb[3 * t + 2]}));
  EXPECT_TRUE(fs::exists(result / "confidence.png"));
  double shares = 0;
  const Json summary = readJson(result / "confidence.json");
  for (const auto& [kind, share] : summary.at("all").items())
    if (kind != "texels") shares += share.get<double>();
  EXPECT_NEAR(shares, 1.0, 1e-9);
}
}  // namespace

TEST(AlbedoSmoothing, StandardErrorsAreTheFitsNoiseAndSmoothingLowersTheError) {
  const fs::path dir = preparedRoom256("albedo_smoothing");
  const SceneDescription truth = loadSceneFile(dir / "capture" / "gt" / "scene.json");
  const Image coverage = readImage(dir / "work" / "coverage.exr");
  FitConfig c = smallFitConfig();
  c.checkpointEvery = 1000;
  c.emissionIterations = 40, c.albedoPasses = 12, c.materialIterations = 0;
  const auto fitted = [&](AlbedoSmoothing smoothing) {
    c.albedoSmoothing = smoothing;
    runFit(dir / "work", c, false);
    const fs::path scene = dir / "work" / "result" / "scene.json";
    EXPECT_TRUE(fs::exists(dir / "work" / "result" / "albedo_stderr.exr"));
    expectConfidenceCarriesTheStandardErrors(dir / "work" / "result");
    return compareWithTruth(loadSceneFile(scene), truth, coverage, truthOptionsFor(scene));
  };
  const TruthComparison raw = fitted(AlbedoSmoothing::None);
  const TruthComparison smoothed = fitted(FitConfig{}.albedoSmoothing);
  const double rawRms = raw.albedoErrorRms(), smoothedRms = smoothed.albedoErrorRms();
  std::printf("AlbedoSmoothing: as fitted MAE %.4f, RMS %.4f, standard errors RMS %.4f, %.1f%% within two\n",
              raw.albedoMae, rawRms, raw.albedoStandardErrorRms, 100 * raw.albedoWithinTwoStandardErrors);
  std::printf("AlbedoSmoothing: smoothed MAE %.4f, RMS %.4f, standard errors RMS %.4f, %.1f%% within two\n",
              smoothed.albedoMae, smoothedRms, smoothed.albedoStandardErrorRms,
              100 * smoothed.albedoWithinTwoStandardErrors);
  // As fitted, the error is mostly the visits' noise: the standard errors account for most of it
  // and bound most errors (not all: the shared biases of a short fit are not in them).
  EXPECT_GT(raw.albedoStandardErrorRms, 0.6 * rawRms);
  EXPECT_LT(raw.albedoStandardErrorRms, 1.2 * rawRms);
  EXPECT_GT(raw.albedoWithinTwoStandardErrors, 0.7);
  // Smoothed: nearer the truth, and the errors it reports fell with it.
  EXPECT_LT(smoothed.albedoMae, 0.8 * raw.albedoMae);
  EXPECT_LT(smoothed.albedoStandardErrorRms, 0.6 * raw.albedoStandardErrorRms);
}
