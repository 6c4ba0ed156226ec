// Known-answer fits on 8-bit captures the test makes itself: the synthetic room's frames encoded
// as a camera would deliver them, each with a white balance nobody recorded.
#include <gtest/gtest.h>

#include <cmath>

#include "capture/frame_image.h"
#include "io/image.h"
#include "io/json.h"
#include "product/evaluate.h"
#include "product/fit.h"
#include "scene/appearance.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// Frame i's true white balance: a few percent per channel, different in every frame.
Color trueGain(size_t i) {
  const double x = static_cast<double>(i);
  return Color(static_cast<float>(1 + 0.05 * std::sin(1.7 * x)), static_cast<float>(1 + 0.04 * std::cos(2.3 * x)),
               static_cast<float>(1 - 0.05 * std::sin(0.9 * x + 1)));
}

// Rewrites the capture's frames as 8-bit sRGB PNG of gain x radiance (the ceiling panels, at
// radiance ~11, store 255), with no exposure recorded.
void toEightBitWithWhiteBalance(const fs::path& capture) {
  Capture cap = readTransforms(capture / "transforms.json");
  for (size_t i = 0; i < cap.frames.size(); ++i) {
    Frame& f = cap.frames[i];
    Image img = loadFrameImage(f);
    for (size_t k = 0; k < img.rgb.size(); ++k) img.rgb[k] *= trueGain(i)[static_cast<int>(k % 3)];
    f.image.replace_extension(".png");
    writeSrgbPng(f.image, img, 8);
    f.exposureRecorded = false;
  }
  writeTransforms(capture / "transforms.json", cap.frames);
}

FitConfig smallConfig() {
  FitConfig c;
  c.batchTexels = 2048;
  c.maxDepth = 4;
  c.emissionIterations = 80;
  c.materialIterations = 20;
  c.albedoPasses = 40;
  c.emissionTextureIterations = 0;
  c.checkpointEvery = 1000;
  return c;
}

}  // namespace

// The fit recovers every frame's white balance (in the gauge: geometric mean 1) to within 1.5%
// and the ceiling panels' emission although every frame stores them at 255: the saturated pixels
// only bound the loss from below, and the light the panels cast fixes their emission.
TEST(LdrFit, RecoversUnrecordedWhiteBalanceAndSaturatedLights) {
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 8, so.testSpp = 8;
  so.atlasResolution = 256;
  const fs::path dir = preparedCapture("ldr_fit", so, 256, toEightBitWithWhiteBalance);
  const FitSummary summary = runFit(dir / "work", smallConfig(), false);

  const Json gains = readJson(dir / "work" / "result" / "frames.json");
  ASSERT_EQ(gains.at("mode"), "rgb");  // auto: 8-bit frames without a recorded exposure
  Eigen::Array3d logMean = Eigen::Array3d::Zero();
  for (const Json& f : gains["frames"]) logMean += trueGain(f["frame"].get<size_t>()).cast<double>().log();
  const Color gauge = (logMean / static_cast<double>(gains["frames"].size())).exp().cast<float>();
  float worst = 0;
  for (const Json& f : gains["frames"]) {
    const Color truth = trueGain(f["frame"].get<size_t>()) / gauge;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(f["gain"][c].get<float>() / truth[c] - 1));
  }
  EXPECT_LT(worst, 0.015f);

  const SceneDescription fit = loadSceneFile(dir / "work" / "result" / "scene.json");
  const SceneDescription truth = loadSceneFile(dir / "capture" / "gt" / "scene.json");
  const TruthComparison score = compareWithTruth(fit, truth, readImage(dir / "work" / "coverage.exr"), {});
  EXPECT_EQ(score.emittersCorrect, score.emittersTrue);
  EXPECT_LT(score.emissionRelError, 0.3);
  std::printf("LdrFit: worst gain error %.2f%%, emission error %.1f%%, albedo MAE %.4f, %zu emitters\n", 100 * worst,
              100 * score.emissionRelError, score.albedoMae, summary.emitters.size());
}
