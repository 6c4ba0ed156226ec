#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/rng.h"
#include "sampling/median_sketch.h"

using namespace relume;

namespace {

// Both passes over `values[t]` for every texel t, as prepare runs them.
void sketchAll(MedianSketch& s, const std::vector<std::vector<Color>>& values) {
  for (size_t t = 0; t < values.size(); ++t)
    for (const Color& c : values[t]) s.addCoarse(t, c);
  s.startFine();
  for (size_t t = 0; t < values.size(); ++t)
    for (const Color& c : values[t]) s.addFine(t, c);
}

std::vector<std::vector<Color>> randomObservations(uint64_t seed, size_t texels) {
  Pcg32 rng(seed);
  std::vector<std::vector<Color>> values(texels);
  for (auto& v : values) {
    const int n = 1 + static_cast<int>(rng.next1D() * 40);
    for (int i = 0; i < n; ++i)  // log-uniform over 1e-3 .. 1e2
      v.push_back(Color(std::pow(10.0f, -3 + 5 * rng.next1D()), std::pow(10.0f, -3 + 5 * rng.next1D()),
                        std::pow(10.0f, -3 + 5 * rng.next1D())));
  }
  return values;
}

}  // namespace

// The sketch's median lies within one sub-bin (8/16/32 decades: a factor 1.036) of the exact
// median, for odd counts where the median is one of the values; its count is the observations'.
TEST(MedianSketch, MedianIsWithinOneSubBinOfTheExactOne) {
  const auto values = randomObservations(7, 200);
  MedianSketch s(values.size());
  sketchAll(s, values);
  const float subBin = std::pow(10.0f, (MedianSketch::kLogMax - MedianSketch::kLogMin) / MedianSketch::kBins /
                                           MedianSketch::kSub);
  for (size_t t = 0; t < values.size(); ++t) {
    EXPECT_EQ(s.count(t), values[t].size());
    if (values[t].size() % 2 == 0) continue;
    for (int c = 0; c < 3; ++c) {
      std::vector<float> channel;
      for (const Color& v : values[t]) channel.push_back(v[c]);
      std::nth_element(channel.begin(), channel.begin() + channel.size() / 2, channel.end());
      const float exact = channel[channel.size() / 2];
      EXPECT_LE(s.median(t)[c], exact * subBin) << "texel " << t << " channel " << c;
      EXPECT_GE(s.median(t)[c], exact / subBin) << "texel " << t << " channel " << c;
    }
  }
}

// prepare reuses one sketch for every band of texels: after restart() it gives what a fresh one
// gives, bit for bit, also for a band with fewer texels than the sketch holds.
TEST(MedianSketch, ARestartedSketchGivesWhatAFreshOneGives) {
  const auto first = randomObservations(1, 300), second = randomObservations(2, 250);
  MedianSketch reused(300), fresh(250);
  sketchAll(reused, first);
  reused.restart();
  sketchAll(reused, second);
  sketchAll(fresh, second);
  for (size_t t = 0; t < second.size(); ++t) {
    EXPECT_EQ(reused.count(t), fresh.count(t));
    for (int c = 0; c < 3; ++c) EXPECT_EQ(reused.median(t)[c], fresh.median(t)[c]) << "texel " << t;
  }
}
