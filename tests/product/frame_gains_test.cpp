#include "product/frame_gains.h"

#include <gtest/gtest.h>

#include "core/rng.h"
#include "product/fit_checkpoint.h"

using namespace relume;

namespace {

// Rays of `frames` frames whose references are the true gain times the radiance, and estimates
// of that radiance with path-tracing-like noise (mean 1, spread +-60%); every fifth ray's
// reference is saturated at 1 with an estimate that would say nothing about the gain.
struct GainScene {
  std::vector<Color> truth;
  std::vector<BatchRay> rays;
  std::vector<uint32_t> frameOf;
  std::vector<int> objectOf;
  std::vector<Color> estimates;

  void draw(uint64_t iteration, size_t count) {
    Pcg32 rng(iteration * 7919 + 1);
    rays.clear(), frameOf.clear(), estimates.clear();
    objectOf.assign(count, 0);
    for (size_t j = 0; j < count; ++j) {
      const uint32_t f = rng.nextU32() % truth.size();
      const Color radiance(0.1f + 0.5f * rng.next1D(), 0.1f + 0.5f * rng.next1D(), 0.1f + 0.5f * rng.next1D());
      BatchRay r{Vec3::Zero(), Vec3::UnitZ(), truth[f] * radiance, {0.0f, 1.0f}};
      Color estimate = radiance * (0.4f + 1.2f * rng.next1D());
      if (j % 5 == 0) r.reference = Color::Constant(1.0f), estimate = Color::Constant(0.01f);
      rays.push_back(r), frameOf.push_back(f), estimates.push_back(estimate);
    }
  }
};

const std::vector<Color> kTruth = {Color(1.3f, 1.0f, 0.9f), Color(0.7f, 0.72f, 0.75f), Color(1.0f, 1.05f, 1.1f),
                                   Color(2.0f, 1.9f, 2.1f)};

FrameGains fitted(FrameGainMode mode, int reference, std::vector<Color> truth = kTruth) {
  GainScene scene{truth, {}, {}, {}, {}};
  FrameGains gains(mode, truth.size(), {0, 1, 2, 3}, reference, 0.9f);
  for (uint64_t it = 0; it < 300; ++it) {
    scene.draw(it, 4000);
    gains.update(scene.rays, scene.frameOf, scene.objectOf, {}, scene.estimates);
  }
  return gains;
}

}  // namespace

// The closed-form update recovers each frame's gain to within 1% in the geometric-mean gauge,
// unbiased by the estimates' noise and blind to saturated references.
TEST(FrameGains, RgbGainsAreRecoveredInTheGeometricMeanGauge) {
  const FrameGains gains = fitted(FrameGainMode::Rgb, -1);
  Eigen::Array3d logMean = Eigen::Array3d::Zero();
  for (const Color& g : kTruth) logMean += g.cast<double>().log() / 4.0;
  const Color gauge = logMean.exp().cast<float>();
  for (uint32_t f = 0; f < 4; ++f)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(gains.gain(f)[c], kTruth[f][c] / gauge[c], 0.01f * kTruth[f][c]) << f;
}

TEST(FrameGains, AReferenceFrameFixesTheGauge) {
  const FrameGains gains = fitted(FrameGainMode::Rgb, 2);
  EXPECT_TRUE(gains.gain(2).isApprox(Color::Ones()));
  for (uint32_t f = 0; f < 4; ++f)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(gains.gain(f)[c], kTruth[f][c] / kTruth[2][c], 0.01f * kTruth[f][c]);
}

// Exposure mode: one scalar per frame, however the channels differ.
TEST(FrameGains, ExposureGainsAreOneScalarPerFrame) {
  const std::vector<Color> grey = {Color::Constant(1.5f), Color::Constant(0.5f), Color::Constant(1.0f),
                                   Color::Constant(2.0f)};
  const FrameGains gains = fitted(FrameGainMode::Exposure, -1, grey);
  const float gauge = std::pow(1.5f * 0.5f * 1.0f * 2.0f, 0.25f);  // the geometric mean
  for (uint32_t f = 0; f < 4; ++f) {
    EXPECT_EQ(gains.gain(f)[0], gains.gain(f)[1]);
    EXPECT_EQ(gains.gain(f)[0], gains.gain(f)[2]);
    EXPECT_NEAR(gains.gain(f)[0], grey[f][0] / gauge, 0.01f * grey[f][0]);
  }
}

// Rays carry their frame's gain; without estimation every gain stays 1.
TEST(FrameGains, ApplySetsEachRaysGain) {
  FrameGains none(FrameGainMode::None, 2, {0, 1}, -1, 0.9f);
  GainScene scene{{Color::Constant(2.0f), Color::Constant(0.5f)}, {}, {}, {}, {}};
  scene.draw(0, 100);
  none.update(scene.rays, scene.frameOf, scene.objectOf, {}, scene.estimates);
  none.apply(scene.rays, scene.frameOf);
  for (const BatchRay& r : scene.rays) EXPECT_TRUE(r.gain.isApprox(Color::Ones()));
  const FrameGains rgb = fitted(FrameGainMode::Rgb, -1);
  GainScene other{kTruth, {}, {}, {}, {}};
  other.draw(1, 50);
  rgb.apply(other.rays, other.frameOf);
  for (size_t j = 0; j < other.rays.size(); ++j) EXPECT_EQ(other.rays[j].gain[1], rgb.gain(other.frameOf[j])[1]);
}

// A checkpoint holds the gains and their evidence: a fit resumed from it updates them exactly as
// the uninterrupted one does.
TEST(FrameGains, ACheckpointContinuesThemExactly) {
  GainScene scene{kTruth, {}, {}, {}, {}};
  FrameGains whole(FrameGainMode::Rgb, 4, {0, 1, 2, 3}, -1, 0.9f);
  for (uint64_t it = 0; it < 20; ++it) {
    scene.draw(it, 500);
    whole.update(scene.rays, scene.frameOf, scene.objectOf, {}, scene.estimates);
  }
  Checkpoint ck;
  CheckpointIo writer = CheckpointIo::writer(ck);
  whole.serialise(writer);
  FrameGains resumed(FrameGainMode::Rgb, 4, {0, 1, 2, 3}, -1, 0.9f);
  CheckpointIo reader = CheckpointIo::reader(ck);
  resumed.serialise(reader);
  for (uint64_t it = 20; it < 30; ++it) {
    scene.draw(it, 500);
    whole.update(scene.rays, scene.frameOf, scene.objectOf, {}, scene.estimates);
    resumed.update(scene.rays, scene.frameOf, scene.objectOf, {}, scene.estimates);
  }
  for (uint32_t f = 0; f < 4; ++f)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(whole.gain(f)[c], resumed.gain(f)[c]);
}
