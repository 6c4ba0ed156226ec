// A fit within a memory budget (product/memory_budget.h): the plan's choice, its bytes per texel
// against what a fit holds, and a whole fit that takes the coarser resolution or refuses up front.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include <tbb/global_control.h>

#include "core/error.h"
#include "io/json.h"
#include "product/fit.h"
#include "product/memory_budget.h"
#include "product/report.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

constexpr double kMiB = 1 << 20;

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(MemoryBudget, TakesTheFinestResolutionThatFitsAndRefusesWhenNoneDoes) {
  TexelBytes b;
  b.albedo = 12, b.texelMap = 5, b.stepState = 30, b.gradients = 26, b.average = 12;  // 85 per texel in the stage
  b.settling = 90;  // more at its end: 12 + 5 + 90 = 107
  EXPECT_EQ(b.peak(), 107);
  const double fixed = 100 * kMiB;
  // 1024^2 x 107 B = 107 MiB; 2048^2: 428 MiB; 4096^2: 1712 MiB.
  const std::vector<int> res{1024, 2048, 4096};
  const double usable = 1 - MemoryPlan::kReserve;  // of the budget
  EXPECT_EQ(planMemory(2048 * kMiB, res, fixed, 10 * kMiB, b).resolution, 4096);
  EXPECT_EQ(planMemory(1812 * kMiB / usable, res, fixed, 10 * kMiB, b).resolution, 4096);  // exactly at the budget
  EXPECT_EQ(planMemory(1811 * kMiB / usable, res, fixed, 10 * kMiB, b).resolution, 2048);
  EXPECT_EQ(planMemory(1812 * kMiB, res, fixed, 10 * kMiB, b).resolution, 2048);  // the reserve is kept
  const MemoryPlan p = planMemory(600 * kMiB, res, fixed, 10 * kMiB, b);
  EXPECT_EQ(p.resolution, 2048);
  ASSERT_EQ(p.estimates.size(), 3u);
  EXPECT_EQ(p.estimates[1].peakBytes(), 528 * kMiB);
  EXPECT_EQ(p.toJson()["predicted"][2]["peak_bytes"].get<double>(), 1812 * kMiB);
  const std::string refused = errorOf([&] { planMemory(200 * kMiB, res, fixed, 10 * kMiB, b); });
  EXPECT_NE(refused.find("memory budget 200 MiB is too small"), std::string::npos) << refused;
  EXPECT_NE(refused.find("207 MiB at its coarsest albedo resolution 1024^2"), std::string::npos) << refused;
  EXPECT_NE(refused.find("a budget of 218 MiB"), std::string::npos) << refused;
  EXPECT_NE(refused.find("100 MiB of it whatever the resolution, 10.0 MiB of that the frame cache"), std::string::npos)
      << refused;
}

// The bytes per texel the plan counts are what a fit holds at its largest stage (fitMemory's
// parts that grow with the resolution), so the model follows the code: a per-texel array added to
// the fit and not to the model fails this. Under the defaults (Gauss-Newton with standard errors,
// Polyak average) and under the paper's Adam step without an average.
TEST(MemoryBudget, BytesPerTexelAreWhatAFitHolds) {
  const fs::path work = smallPreparedRoom("memory_budget_bytes") / "work";
  FitConfig c;
  c.batchTexels = 256, c.framesPerTexel = 2, c.maxDepth = 3;
  c.emissionIterations = 6, c.materialIterations = 8, c.emissionTextureIterations = 0, c.albedoPasses = 2;
  c.checkpointEvery = 1000000;
  FitConfig adam = c;
  adam.albedoStep = AlbedoStep::Adam, adam.polyakFraction = 0, adam.materialPolyakFraction = 0;
  for (const FitConfig& config : {c, adam}) {
    FitHooks hooks;
    hooks.writeFiles = false;
    double texels = 0;
    Json m;  // the settling stage's (materials: the albedo at its finest, and its average)
    hooks.afterIteration = [&](const FitIteration& it) {
      texels = static_cast<double>(it.appearance.albedo.rgb.size() / 3);
      if (it.stage == "materials") m = it.stageMemory;
      return true;
    };
    runFit(work, config, false, hooks);
    ASSERT_GT(texels, 0);
    EXPECT_EQ(m.at("averages").get<double>() > 0, config.polyakFraction > 0) << m.dump();
    double held = 0;
    for (const char* part : {"parameters", "gradients", "optimiser_state", "averages", "texel_map"})
      held += m.at(part).get<double>();
    // The sampleable fraction from the texel map's part: 4 bytes of index and 1 of flag per texel,
    // 4 per sampleable texel.
    const double sampleable = (m.at("texel_map").get<double>() / texels - 5) / 4;
    ASSERT_GT(sampleable, 0.05);
    const TexelBytes b = texelBytes(config, sampleable);
    // The model counts the sampleable list at twice its size (the vector's growth) and leaves out
    // the per-object parameters and the gradient logs' bookkeeping.
    const double modelled = (b.stage() - 4 * sampleable) * texels;
    EXPECT_NEAR(modelled / held, 1.0, 0.03)
        << enumName(config.albedoStep) << ": held " << held << " bytes, modelled " << modelled << ": " << m.dump();
  }
}

namespace {

// The room prepared at 64^2 and 128^2 in a fresh folder; returns the work folder.
fs::path roomAtTwoResolutions(const std::string& name) {
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 2, so.testSpp = 2;
  so.atlasResolution = 128;
  const fs::path dir = fs::temp_directory_path() / ("relume_" + name);
  fs::remove_all(dir);
  so.out = dir / "capture";
  writeSynthCapture(so);
  PrepareOptions po;
  po.resolutions = {64, 128};
  po.atlas.gutterResolution = 64;  // at the coarser resolution: each prepared one is a multiple of it
  prepareCapture(so.out, dir / "work", po);
  return dir / "work";
}

// A short fit to 128^2 (the finer of the two).
FitConfig shortFit() {
  FitConfig c;
  c.batchTexels = 256, c.framesPerTexel = 2, c.maxDepth = 3, c.maxResolution = 128;
  c.emissionIterations = 4, c.materialIterations = 4, c.emissionTextureIterations = 2, c.albedoPasses = 1;
  return c;
}

// The predicted peak at 128^2 of a fit on `threads` threads, from its materials.json.
double finePrediction(const fs::path& work, FitConfig c, int threads) {
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(threads));
  c.memoryBudgetMib = 1e6;
  EXPECT_EQ(runFit(work, c, false).finalResolution, 128);
  return readJson(work / "result" / "materials.json").at("memory_budget").at("predicted")[1].at("peak_bytes");
}

}  // namespace

// A budget between the two resolutions' predicted peaks fits at 64^2; one below both refuses the
// fit before its first iteration.
TEST(FitMemoryBudget, TakesTheCoarserResolutionOrRefusesUpFront) {
  const fs::path work = roomAtTwoResolutions("memory_budget_fit");
  FitConfig c = shortFit();
  c.memoryBudgetMib = 1e6;
  EXPECT_EQ(runFit(work, c, false).finalResolution, 128);
  const Json plan = readJson(work / "result" / "materials.json").at("memory_budget");
  EXPECT_EQ(plan.at("resolution").get<int>(), 128);
  const double coarse = plan.at("predicted")[0].at("peak_bytes").get<double>(),
               fine = plan.at("predicted")[1].at("peak_bytes").get<double>();
  ASSERT_LT(coarse, fine);

  c.memoryBudgetMib = static_cast<float>(0.5 * (coarse + fine) / (1 - MemoryPlan::kReserve) / kMiB);
  EXPECT_EQ(runFit(work, c, false).finalResolution, 64);
  EXPECT_EQ(readJson(work / "result" / "materials.json").at("memory_budget").at("resolution").get<int>(), 64);
  std::ifstream page(writeFitReport(work));
  const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("so the albedo went up to 64^2"), std::string::npos);

  fs::remove_all(work / "result");
  c.memoryBudgetMib = static_cast<float>(coarse / kMiB);  // the prediction without the reserve
  FitHooks hooks;
  int iterations = 0;
  hooks.afterIteration = [&](const FitIteration&) { return ++iterations > 0; };
  const std::string refused = errorOf([&] { runFit(work, c, false, hooks); });
  EXPECT_NE(refused.find("is too small for this fit"), std::string::npos) << refused;
  EXPECT_EQ(iterations, 0);
  EXPECT_FALSE(fs::exists(work / "result"));
}

// A resumed fit keeps the resolution the interrupted run planned, which its schedule and
// checkpoint were built for, although its own prediction differs: the path records are per
// thread, so on 2 threads the 128^2 prediction is above a budget that held it on 1.
TEST(FitMemoryBudget, AResumedFitKeepsTheInterruptedRunsResolution) {
  const fs::path work = roomAtTwoResolutions("memory_budget_resume");
  FitConfig c = shortFit();
  const double one = finePrediction(work, c, 1), two = finePrediction(work, c, 2);
  ASSERT_LT(one, two);
  c.memoryBudgetMib = static_cast<float>(0.5 * (one + two) / (1 - MemoryPlan::kReserve) / kMiB);
  fs::remove_all(work / "result");
  {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    c.stopAfterIterations = 6;  // in the first albedo stage
    EXPECT_TRUE(runFit(work, c, false).stopped);
  }
  c.stopAfterIterations = 0;
  const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const FitSummary resumed = runFit(work, c, true);
  EXPECT_EQ(resumed.finalResolution, 128);
  const Json m = readJson(work / "result" / "materials.json");
  EXPECT_EQ(m.at("albedo_resolution").get<int>(), 128);
  EXPECT_EQ(m.at("memory_budget").at("resolution").get<int>(), 128);
  fs::remove_all(work / "result");
  EXPECT_EQ(runFit(work, c, false).finalResolution, 64);  // a new fit on 2 threads plans its own
}
