// Albedo stages that end once their albedo only averages its noise (stop_on_convergence,
// optim/albedo_convergence.h): where they end, what the result says, and a resumed fit.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "core/error.h"

#include "io/json.h"
#include "product/fit.h"
#include "product/report.h"
#include "support/fitted_values.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

FitConfig convergingConfig() {
  FitConfig c;
  c.batchTexels = 256, c.framesPerTexel = 2, c.maxDepth = 3;
  c.emissionIterations = 40, c.materialIterations = 16, c.emissionTextureIterations = 12;
  c.albedoPasses = 60;
  c.checkpointEvery = 1000000;
  c.stopOnConvergence = true;
  c.convergenceStandardError = 0.25f;  // this capture's albedo starts at 0.32 (16 frames of 64x48 at 2 spp)
  return c;
}

std::vector<Json> convergenceChecks(const fs::path& work) {
  std::vector<Json> checks;
  std::ifstream metrics(work / "metrics.jsonl");
  for (std::string line; std::getline(metrics, line);)
    if (Json j = Json::parse(line); j.contains("convergence")) checks.push_back(j["convergence"]);
  return checks;
}

}  // namespace

TEST(StopOnConvergence, TheAlbedoStageEndsOnceItsMovementIsItsNoiseAndAResumedFitEndsThere) {
  const fs::path dir = smallPreparedRoom("stop_on_convergence"), work = dir / "work";
  const FitSummary whole = runFit(work, convergingConfig(), false, FitHooks{});
  const std::vector<Json> checks = convergenceChecks(work);
  ASSERT_GE(checks.size(), 3u);
  // The first check only takes the values. Here the albedo moves by its noise alone (ratio
  // 1.009-1.094) from the second check (the movement itself is tested in optim:
  // AlbedoConvergence.*), but that noise is above the tolerance: the stage ends at the first check
  // that finds both.
  EXPECT_EQ(checks.front()["pairs"].get<size_t>(), 0u);
  const double ratio = convergingConfig().convergenceRatio, error = convergingConfig().convergenceStandardError;
  EXPECT_GT(checks[1]["standard_error"].get<double>(), error);
  EXPECT_FALSE(checks.front()["converged"].get<bool>());
  for (size_t i = 1; i + 1 < checks.size(); ++i) {
    EXPECT_FALSE(checks[i]["converged"].get<bool>()) << i;
    EXPECT_TRUE(checks[i]["ratio"].get<double>() > ratio || checks[i]["standard_error"].get<double>() > error) << i;
  }
  EXPECT_TRUE(checks.back()["converged"].get<bool>());
  EXPECT_LE(checks.back()["ratio"].get<double>(), ratio);
  EXPECT_LE(checks.back()["standard_error"].get<double>(), error);
  const Json materials = readJson(work / "result" / "materials.json");
  ASSERT_TRUE(materials.contains("convergence"));
  const Json& stage = materials["convergence"]["stages"][0];
  EXPECT_EQ(stage["stage"], "albedo@128");
  // The stage settles nothing (the material stage after it settles the albedo): it ends at once.
  EXPECT_EQ(stage["converged_at"].get<int>(), checks.back()["stage_iteration"].get<int>());
  EXPECT_EQ(stage["iterations"].get<int>(), stage["converged_at"].get<int>());
  EXPECT_LT(2 * stage["iterations"].get<int>(), stage["longest"].get<int>());
  const std::vector<float> uninterrupted = fittedValues(work);
  std::ifstream page(writeFitReport(work));
  const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find(fmt::format("albedo@128 converged after {} iterations (of at most {})",
                                  stage["converged_at"].get<int>(), stage["longest"].get<int>())),
            std::string::npos);

  // Without it the same passes run to the end.
  FitConfig all = convergingConfig();
  all.stopOnConvergence = false;
  all.maxStageIterations = 1000000;
  fs::remove_all(work / "result");
  const FitSummary fixed = runFit(work, all, false, FitHooks{});
  EXPECT_EQ(fixed.iterations - whole.iterations, stage["longest"].get<int>() - stage["iterations"].get<int>());

  // Stopped between the last two checks of the albedo stage and resumed: the next check compares
  // with the interrupted run's last, so the stage ends where it did.
  fs::remove_all(work / "result");
  FitConfig part = convergingConfig();
  const int first = checks[checks.size() - 2]["stage_iteration"].get<int>(),
            second = checks.back()["stage_iteration"].get<int>();
  part.stopAfterIterations = convergingConfig().emissionIterations + (first + second) / 2;
  const FitSummary stopped = runFit(work, part, false, FitHooks{});
  ASSERT_TRUE(stopped.stopped);
  const FitSummary resumed = runFit(work, convergingConfig(), true, FitHooks{});
  EXPECT_EQ(resumed.iterations, whole.iterations);
  EXPECT_TRUE(fittedValues(work) == uninterrupted) << "the resumed fit differs from the uninterrupted one";
}

// Under a time budget the albedo stage runs what the plan gives it, and ends sooner when it
// converges: the stages after it are planned with the time it leaves, and the fit ends early. The
// budget here is long enough for every stage at its longest, so the plan does not depend on the
// machine's speed: the stage converges where it does without a budget.
TEST(StopOnConvergence, UnderATimeBudgetAConvergedStageEndsTheFitBeforeTheBudget) {
  const fs::path dir = smallPreparedRoom("stop_on_convergence_budget"), work = dir / "work";
  const FitSummary alone = runFit(work, convergingConfig(), false, FitHooks{});
  const Json converged = readJson(work / "result" / "materials.json")["convergence"]["stages"][0];
  fs::remove_all(work / "result");
  fs::remove(work / "metrics.jsonl");
  FitConfig budgeted = convergingConfig();
  budgeted.timeBudget = 1e6;
  const FitSummary fit = runFit(work, budgeted, false, FitHooks{});
  const Json materials = readJson(work / "result" / "materials.json");
  const Json& stage = materials["convergence"]["stages"][0];
  EXPECT_EQ(stage["stage"], "albedo@128");
  EXPECT_EQ(stage["converged_at"], converged["converged_at"]);
  EXPECT_EQ(stage["iterations"], converged["iterations"]);
  EXPECT_LT(stage["iterations"].get<int>(), stage["longest"].get<int>());
  EXPECT_EQ(fit.iterations, alone.iterations);
  // The plans made before the stage converged gave it all its passes; the budget's summary has
  // the length it ended at.
  bool plannedLongest = false;
  std::ifstream metrics(work / "metrics.jsonl");
  for (std::string line; std::getline(metrics, line);)
    if (Json j = Json::parse(line); j.contains("budget") && j["budget"]["stage"] == "albedo@128")
      plannedLongest |= j["budget"]["iterations"][0][1] == stage["longest"];
  EXPECT_TRUE(plannedLongest);
  int ended = -1;
  for (const Json& st : materials["time_budget"]["iterations"])
    if (st[0] == "albedo@128") ended = st[1].get<int>();
  EXPECT_EQ(ended, stage["iterations"].get<int>());
  EXPECT_LT(materials["time_budget"]["fit_seconds"].get<double>(), budgeted.timeBudget);
}
