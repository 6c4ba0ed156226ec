// Pixel filters: Cycles' definitions, sampling that follows them (chi-square), the unit box's identity.
#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "core/pixel_filter.h"
#include "core/rng.h"

using namespace relume;

namespace {

// Mass of the filter over [a, b], in closed form (independent of the filter's table).
double exactMass(const PixelFilter& f, double a, double b) {
  const double r = f.radius(), w = f.width();
  a = std::clamp(a, -r, r), b = std::clamp(b, -r, r);
  switch (f.type()) {
    case PixelFilterType::Box:
      return b - a;
    case PixelFilterType::Gaussian: {  // exp(-8 x^2 / w^2): sigma = w / 4
      const double s = w / 4.0;
      return s * std::sqrt(M_PI / 2.0) * (std::erf(b / (s * std::sqrt(2.0))) - std::erf(a / (s * std::sqrt(2.0))));
    }
    case PixelFilterType::BlackmanHarris: {  // v = 2 pi (x / 2w + 1/2), dx = w / pi dv
      const auto F = [&](double x) {
        const double v = 2.0 * M_PI * (x / (2.0 * w) + 0.5);
        return w / M_PI *
               (0.35875 * v - 0.48829 * std::sin(v) + 0.14128 * std::sin(2 * v) / 2 - 0.01168 * std::sin(3 * v) / 3);
      };
      return F(b) - F(a);
    }
  }
  return 0;
}

}  // namespace

TEST(PixelFilter, CyclesDefinitions) {
  const PixelFilter bh(PixelFilterType::BlackmanHarris, 1.5f), g(PixelFilterType::Gaussian, 1.5f);
  EXPECT_FLOAT_EQ(bh.radius(), 1.5f);  // Cycles' filter_table doubles a Blackman-Harris width
  EXPECT_NEAR(bh.weight(0), 1.0f, 1e-6f);
  EXPECT_NEAR(bh.weight(1.5f), 6e-5f, 1e-6f);
  EXPECT_EQ(bh.weight(1.51f), 0.0f);
  EXPECT_FLOAT_EQ(g.radius(), 2.25f);                       // ... and triples a Gaussian's
  EXPECT_NEAR(g.weight(1.5f / 4), std::exp(-0.5f), 1e-6f);  // sigma = width / 4
  EXPECT_EQ(PixelFilter().radius(), 0.5f);
}

TEST(PixelFilter, UnitBoxSampleIsTheUniformNumberItself) {
  const PixelFilter box;
  ASSERT_TRUE(box.isUnitBox());
  Pcg32 rng(7);
  for (int i = 0; i < 10000; ++i) {
    const float u = rng.next1D();
    ASSERT_EQ(box.sample(u), u);
  }
  EXPECT_EQ(box.sample(0.0f), 0.0f);
  const PixelFilter wide(PixelFilterType::Box, 2.0f);
  EXPECT_FALSE(wide.isUnitBox());
  EXPECT_FLOAT_EQ(wide.sample(0.0f), -0.5f);
  EXPECT_FLOAT_EQ(wide.sample(0.75f), 1.0f);
}

// Chi-square of 200,000 samples in 30 bins against the closed-form mass of each bin: 29 degrees of
// freedom, 0.1% critical value 58.3. A uniform draw over the support (a box of the same radius)
// fails it by orders of magnitude.
TEST(PixelFilter, SamplesFollowTheFilter) {
  for (const PixelFilter& f :
       {PixelFilter(PixelFilterType::BlackmanHarris, 1.5f), PixelFilter(PixelFilterType::Gaussian, 1.5f),
        PixelFilter(PixelFilterType::BlackmanHarris, 0.7f), PixelFilter(PixelFilterType::Box, 2.5f)}) {
    const int bins = 30, n = 200000;
    const double r = f.radius(), total = exactMass(f, -r, r);
    std::vector<int> count(bins, 0);
    Pcg32 rng(11);
    for (int i = 0; i < n; ++i) {
      const double x = f.sample(rng.next1D()) - 0.5;
      ASSERT_LE(std::abs(x), r + 1e-5) << f.name();
      ++count[std::clamp(int((x + r) / (2 * r) * bins), 0, bins - 1)];
    }
    double chi2 = 0, chi2Uniform = 0;
    for (int b = 0; b < bins; ++b) {
      const double expected = n * exactMass(f, -r + 2 * r * b / bins, -r + 2 * r * (b + 1) / bins) / total;
      chi2 += (count[b] - expected) * (count[b] - expected) / expected;
      chi2Uniform += (n / double(bins) - expected) * (n / double(bins) - expected) / expected;
    }
    EXPECT_LT(chi2, 58.3) << f.name() << " width " << f.width();
    if (f.type() != PixelFilterType::Box) {
      EXPECT_GT(chi2Uniform, 1000.0) << f.name();
    }
  }
}

TEST(PixelFilter, RejectsUnknownTypesAndBadWidths) {
  EXPECT_THROW(PixelFilter::parse("mitchell", 1.5), Error);
  for (double w : {0.0, -1.0, 17.0, std::nan("")}) EXPECT_THROW(PixelFilter::parse("gaussian", w), Error) << w;
  EXPECT_EQ(PixelFilter::parse("blackman-harris"), PixelFilter(PixelFilterType::BlackmanHarris, 1.5f));
  EXPECT_EQ(PixelFilter::parseSpec("gaussian:2"), PixelFilter(PixelFilterType::Gaussian, 2.0f));
  EXPECT_TRUE(PixelFilter::parseSpec("box").isUnitBox());
  for (const char* bad : {"box:", "box:wide", "gaussian:1.5px", ":2"})
    EXPECT_THROW(PixelFilter::parseSpec(bad), Error) << bad;
}
