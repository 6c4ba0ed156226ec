#include "capture/photometric_consistency.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/rng.h"

using namespace relume;

// Texels of random radiance seen by overlapping runs of frames, each frame with its own gain per
// channel, 1% noise and one observation in ten a highlight (x3): the gains come back to 0.2% in
// the gauge (geometric mean 1), the highlights held off by the robust weights.
TEST(PhotometricConsistency, RecoversFrameGainsFromTheFramesAlone) {
  const size_t frames = 12;
  std::vector<Color> truth(frames);
  Pcg32 rng(7);
  for (Color& g : truth)
    g = Color(std::exp(0.4f * (rng.next1D() - 0.5f)), std::exp(0.4f * (rng.next1D() - 0.5f)),
              std::exp(0.4f * (rng.next1D() - 0.5f)));
  std::vector<std::vector<GainObservation>> observations(4000);
  for (size_t x = 0; x < observations.size(); ++x) {
    const Color radiance(0.05f + rng.next1D(), 0.05f + rng.next1D(), 0.05f + rng.next1D());
    const size_t first = rng.nextU32() % frames, count = 2 + rng.nextU32() % 4;  // a run of 2-5 frames
    for (size_t i = 0; i < count; ++i) {
      const uint32_t f = static_cast<uint32_t>((first + i) % frames);
      const float noise = 1.0f + 0.01f * (2 * rng.next1D() - 1), highlight = rng.next1D() < 0.1f ? 3.0f : 1.0f;
      observations[x].push_back({f, truth[f] * radiance * noise * highlight});
    }
  }
  std::vector<uint32_t> kept(frames);
  for (uint32_t f = 0; f < frames; ++f) kept[f] = f;
  const ConsistencyGains g = solveConsistencyGains(observations, frames, kept);
  Eigen::Array3d logMean = Eigen::Array3d::Zero();
  for (const Color& t : truth) logMean += t.cast<double>().log() / static_cast<double>(frames);
  const Color gauge = logMean.exp().cast<float>();
  for (uint32_t f = 0; f < frames; ++f) {
    EXPECT_GT(g.texels[f], 100u);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(g.gain[f][c] / (truth[f][c] / gauge[c]), 1.0f, 0.002f) << f << " " << c;
  }
}

// A frame tied to no other keeps gain 1; a frame outside `kept` is never touched.
TEST(PhotometricConsistency, UntiedFramesKeepGainOne) {
  std::vector<std::vector<GainObservation>> observations = {
      {{0, Color::Constant(1.0f)}, {1, Color::Constant(2.0f)}},
      {{2, Color::Constant(5.0f)}},  // one observation: no tie
  };
  const ConsistencyGains g = solveConsistencyGains(observations, 4, std::vector<uint32_t>{0, 1, 2});
  EXPECT_NEAR(g.gain[1][0] / g.gain[0][0], 2.0f, 1e-4f);
  EXPECT_NEAR(g.gain[2][0], 1.0f, 1e-3f);
  EXPECT_EQ(g.gain[3][0], 1.0f);
  EXPECT_EQ(g.texels[2], 0u);
}
