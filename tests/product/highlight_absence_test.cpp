// Known answer: the built-in room's rough objects (walls 0.8, ceiling 0.9, rug 0.95, sofa 0.9 in
// its truth) show no highlight in any frame. What that absence rules out moves their roughness
// from the init (0.5) towards the truth; the glossy objects are fitted as before.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "io/json.h"
#include "product/fit.h"
#include "scene/appearance.h"
#include "support/prepared_capture.h"
#include "support/small_fit_config.h"

using namespace relume;
namespace fs = std::filesystem;

TEST(HighlightAbsence, RoughObjectsWithoutAHighlightAreFittedRougher) {
  const fs::path dir = preparedRoom256("highlight_absence");
  const Appearance truth = loadSceneFile(dir / "capture" / "gt" / "scene.json").appearance;
  FitConfig c = smallFitConfig();
  c.checkpointEvery = 1000;
  // The bound is taken before the material stage, under the first albedo stage's albedo.
  c.emissionIterations = 30, c.albedoPasses = 4, c.materialIterations = 0, c.lightRedecide = false;
  const auto fitted = [&](bool absence) {
    c.highlightAbsence = absence;
    runFit(dir / "work", c, false);
    return readJson(dir / "work" / "result" / "materials.json")["objects"];
  };
  const Json with = fitted(true);
  double errorBounded = 0, errorInit = 0;
  int bounded = 0;
  for (const Json& o : with) {
    const int id = o["id"].get<int>();
    const double r = o["roughness"].get<double>(), t = truth.roughness[id];
    if (o["highlight_observed"].get<bool>()) {
      EXPECT_TRUE(o["roughness_at_least"].is_null()) << o.dump();
      continue;
    }
    if (o["roughness_at_least"].is_null()) {
      EXPECT_FLOAT_EQ(r, 0.5f) << o.dump();  // nothing tested: the init
      continue;
    }
    ++bounded;
    EXPECT_GE(r, o["roughness_at_least"].get<double>()) << o.dump();
    errorBounded += std::abs(r - t), errorInit += std::abs(0.5 - t);
    std::printf("HighlightAbsence: %s roughness %.2f (at least %.1f), truth %.2f\n", o["name"].get<std::string>().c_str(),
                r, o["roughness_at_least"].get<double>(), t);
  }
  ASSERT_GE(bounded, 3);
  EXPECT_LT(errorBounded / bounded, errorInit / bounded - 0.1);
  std::printf("HighlightAbsence: %d objects bounded, roughness MAE %.3f (init %.3f)\n", bounded, errorBounded / bounded,
              errorInit / bounded);
  // The ablation keeps every object without a highlight at the init, unbounded.
  for (const Json& o : fitted(false))
    if (!o["highlight_observed"].get<bool>()) {
      EXPECT_TRUE(o["roughness_at_least"].is_null()) << o.dump();
      EXPECT_FLOAT_EQ(o["roughness"].get<float>(), 0.5f) << o.dump();
    }
}
