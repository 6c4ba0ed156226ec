// References at the ends of the sensor (all saturated, all dark), NaN/Inf pixels, and captures
// so thin that every texel is seen by one frame.
#include "extremes.h"

#include "capture/transforms.h"
#include "core/error.h"
#include "io/image.h"

using namespace relume;
using namespace relume::extremes;
namespace fs = std::filesystem;

namespace {

struct ClippedBatch {
  double loss = 0;
  Gradients grads;
};

// One iteration's loss and gradients on the Cornell batch with every reference replaced.
ClippedBatch withReferences(const GradientExperiment& e, const Color& reference, ClipThresholds clip) {
  std::vector<BatchRay> rays = e.rays;
  for (BatchRay& r : rays) r.reference = reference, r.clip = clip;
  const Scene scene(e.truth.mesh);
  const LightSampler lights(scene, e.current);
  AdjointSettings s;
  s.path.maxDepth = 4;
  ClippedBatch out{0, Gradients(e.current, true)};
  out.loss = computeGradients(scene, e.current, lights, rays, s, 0, out.grads).loss;
  EXPECT_TRUE(allFinite(out.grads));
  return out;
}

bool allZero(std::span<const float> v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return x == 0.0f; });
}

}  // namespace

TEST(ExtremeReferences, ClippedReferencesCarryNoGradientOnTheFreeSideAndPullOneWayBeyondIt) {
  const GradientExperiment e = cornell();
  const float big = 1e3f;  // far beyond any estimate of the Cornell box (its light is 17)
  const Scene scene(e.truth.mesh);
  for (const Color& c : estimates(scene, e.current, e.rays, 4)) ASSERT_LT(c.maxCoeff(), big);
  // All saturated at a threshold every estimate reaches (0), or all dark below a threshold no
  // estimate reaches: the one-sided loss has nothing to say. Bound: loss and every gradient 0.
  for (const auto& [reference, clip] : {std::pair{Color::Zero().eval(), ClipThresholds{-1.0f, 0.0f}},
                                        std::pair{Color::Zero().eval(), ClipThresholds{big, INFINITY}}}) {
    const ClippedBatch b = withReferences(e, reference, clip);
    EXPECT_EQ(b.loss, 0.0);
    EXPECT_TRUE(allZero(b.grads.albedo) && allZero(b.grads.objects) && allZero(b.grads.albedoCurvature));
  }
  // All saturated above every estimate: every ray is pulled up to the threshold, so raising any
  // albedo or emission lowers the loss. Bound: those gradients are <= 0 and some are < 0.
  const ClippedBatch up = withReferences(e, Color::Constant(2 * big), {0.0f, big});
  EXPECT_GT(up.loss, 0.0);
  EXPECT_LE(*std::max_element(up.grads.albedo.begin(), up.grads.albedo.end()), 0.0f);
  EXPECT_LT(*std::min_element(up.grads.albedo.begin(), up.grads.albedo.end()), 0.0f);
  for (int o = 0; o < e.current.objectCount(); ++o)
    for (int c = 0; c < 3; ++c) EXPECT_LE(up.grads.objects[up.grads.emissionSlot(o, c)], 0.0f);
  // All dark (reference 0 at threshold 0): every positive estimate is pulled down. Bound: the
  // albedo and emission gradients are >= 0.
  const ClippedBatch down = withReferences(e, Color::Zero(), {0.0f, INFINITY});
  EXPECT_GT(down.loss, 0.0);
  EXPECT_GE(*std::min_element(down.grads.albedo.begin(), down.grads.albedo.end()), 0.0f);
  for (int o = 0; o < e.current.objectCount(); ++o)
    for (int c = 0; c < 3; ++c) EXPECT_GE(down.grads.objects[down.grads.emissionSlot(o, c)], 0.0f);
}

TEST(ExtremeReferences, ACaptureWithEveryPixelSaturatedIsAOneLineError) {
  // Every frame is 100% overexposed, so prepare drops them all: an error, not a fit to nothing.
  EXPECT_THROW(tinyCapture("saturated", 2,
                           [](const fs::path& capture) {
                             Json t = readJson(capture / "transforms.json");
                             t["clip_high"] = 1e-6;
                             writeJson(capture / "transforms.json", t);
                           }),
               Error);
}

TEST(ExtremeReferences, NonFinitePixelsAreMaskedAndTheFitStaysBounded) {
  // A quarter of every frame's pixels NaN, +Inf or -Inf (a stripe of each).
  const fs::path dir = tinyCapture("nonfinite", 4, [](const fs::path& capture) {
    for (const Frame& f : readTransforms(capture / "transforms.json").frames) {
      Image img = readImage(f.image);
      for (size_t p = 0; p < img.rgb.size() / 3; ++p)
        if (p % 4 == 0) img.rgb[3 * p + p / 4 % 3] = p % 3 == 0 ? NAN : (p % 3 == 1 ? INFINITY : -INFINITY);
      writeExr(f.image, img);
    }
  });
  const Json prepared = readJson(dir / "work" / "prepare.json");
  EXPECT_EQ(prepared["phases"]["frames"]["masked_pixel_fraction"].size(), 4u) << prepared["phases"]["frames"].dump();
  runFit(dir / "work", tinyFit(), false);
  expectBoundedFit(dir);
}

TEST(ExtremeReferences, AOneFrameCaptureFitsToABoundedResult) {
  // One frame: every texel's connections are that frame's pixels, so the Gauss-Newton albedo step
  // fits each texel to a single view and the light to what one view shows.
  const fs::path dir = tinyCapture("oneframe", 1);
  const FitSummary s = runFit(dir / "work", tinyFit(), false);
  EXPECT_FALSE(s.stopped);
  expectBoundedFit(dir);
  // Bound: the fitted albedo moved from its init wherever the frame saw it (the fit did work).
  const SceneDescription fit = loadSceneFile(dir / "work" / "result" / "scene.json");
  const Image init = readImage(dir / "work" / "albedo_init.exr");
  size_t moved = 0;
  for (size_t i = 0; i < init.rgb.size(); ++i) moved += std::abs(fit.appearance.albedo.rgb[i] - init.rgb[i]) > 1e-3f;
  EXPECT_GT(moved, 100u);
}
