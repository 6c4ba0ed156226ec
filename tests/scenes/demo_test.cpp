// The demo's options: its training frames and fit are those its results were measured with (only
// the held-out views, which the fit never sees, are its own).
#include <gtest/gtest.h>

#include "scenes/demo.h"

using namespace relume;

TEST(Demo, TrainsOnSynthsDefaultFramesAndOnlyTheHeldOutViewsDiffer) {
  const SynthCaptureOptions d = DemoOptions::captureOptions("cap"), s;
  EXPECT_EQ(d.out, "cap");
  EXPECT_EQ(d.kind, s.kind);
  EXPECT_EQ(d.frames, s.frames);
  EXPECT_EQ(d.width, s.width);
  EXPECT_EQ(d.height, s.height);
  EXPECT_EQ(d.spp, s.spp);
  EXPECT_EQ(d.maxDepth, s.maxDepth);
  EXPECT_EQ(d.seed, s.seed);
  EXPECT_EQ(d.withUv, s.withUv);
  EXPECT_EQ(d.atlasResolution, s.atlasResolution);
  EXPECT_TRUE(d.pixelFilter.isUnitBox());
  EXPECT_FALSE(d.imperfections);  // a clean capture
  // Held-out views: fewer pixels, fewer samples, the same walk.
  EXPECT_EQ(d.testFrames, s.testFrames);
  EXPECT_EQ(d.testWidth * s.height, d.testHeight * s.width);  // same aspect, so the same field of view
  EXPECT_LT(int64_t{d.testWidth} * d.testHeight * d.testSpp, int64_t{s.width} * s.height * s.testSpp);
}

TEST(Demo, FitsWithItsReducedSchedule) {
  const FitConfig c = DemoOptions::demoFitConfig();
  EXPECT_EQ(c.batchTexels, 8192);
  EXPECT_EQ(c.emissionIterations, 100);
  EXPECT_EQ(c.materialIterations, 150);
  EXPECT_EQ(c.albedoPasses, 40);
  EXPECT_EQ(c.samplesPerRay, 1);
  EXPECT_EQ(c.emissionTextureIterations, 40);
  FitConfig rest = c;  // everything else at the fit's defaults
  rest.batchTexels = FitConfig().batchTexels, rest.emissionIterations = FitConfig().emissionIterations;
  rest.materialIterations = FitConfig().materialIterations, rest.albedoPasses = FitConfig().albedoPasses;
  rest.samplesPerRay = FitConfig().samplesPerRay,
  rest.emissionTextureIterations = FitConfig().emissionTextureIterations;
  EXPECT_EQ(rest.toJson(), FitConfig().toJson());
  const DemoOptions o;
  EXPECT_EQ(o.fit.toJson(), c.toJson());
  EXPECT_GE(o.testSpp, 2);  // rendered as two halves
  EXPECT_GE(o.report.spp, 2);
}
