// A fit within a time budget: the plan from measured costs (product/time_budget.h), and a whole
// fit on a clock the test advances itself, so that what it plans and where it ends are exact.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include "core/error.h"
#include "io/json.h"
#include "product/fit.h"
#include "product/report.h"
#include "product/time_budget.h"
#include "support/fitted_values.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// emission 200 | albedo 2000 (albedo passes) | materials 300 | emission textures 100; the
// materials stage draws twice the texels of the others.
struct FourStages {
  std::vector<Stage> stages;
  std::vector<double> drawn{1000, 1000, 2000, 1000};
  FourStages() {
    for (const auto& [name, n] : std::vector<std::pair<const char*, int>>{
             {"emission", 200}, {"albedo", 2000}, {"materials", 300}, {"emission_texture", 100}})
      stages.push_back({name, ParamMask{0}, 64, n});
    stages[1].lengthFromPasses = true;
  }
};

// The budget after 1 s of setup and 11 emission iterations: the first 0.5 s (it allocates), the
// others 0.05 s each; 2 s spent.
TimeBudget measured(double seconds, const FourStages& f) {
  TimeBudget b(seconds, f.stages, f.drawn);
  b.recordBoundary(1.0);
  b.recordIteration(0, 0.5);
  for (int i = 0; i < 10; ++i) b.recordIteration(0, 0.05);
  return b;
}

// The seconds the stages' lengths cost from 11 iterations into the first, at 0.05 s per 1000
// texels drawn and 1 s per stage boundary (each stage's end, the result's included).
double predicted(const std::vector<Stage>& s, const std::vector<bool>& runs) {
  double t = (s[0].iterations - 11) * 0.05 + 1.0;
  for (size_t i = 1; i < s.size(); ++i)
    if (runs[i]) t += s[i].iterations * (i == 2 ? 0.1 : 0.05) + 1.0;
  return t;
}

const std::vector<bool> kAllRun(4, true);

// A 60 s budget planned in the emission stage, then `count` iterations of the albedo stage
// measured: the first `first` s, the others `each`.
TimeBudget inTheAlbedoStage(FourStages& f, double first, double each, int count) {
  TimeBudget b = measured(60, f);
  b.plan(f.stages, 0, 11, 2.0, kAllRun);
  b.recordBoundary(1.0);
  b.recordIteration(1, first);
  for (int i = 1; i < count; ++i) b.recordIteration(1, each);
  return b;
}

}  // namespace

TEST(TimeBudget, ABudgetLongerThanTheDefaultScheduleEndsWithItWhenNoStageWasCut) {
  FourStages f;  // the albedo stage runs all its passes: max_stage_iterations did not cut it
  TimeBudget b = measured(200, f);
  const Json plan = b.plan(f.stages, 0, 11, 2.0, kAllRun);
  // 10 + 100 + 30 + 5 s of iterations (less the 0.55 s run) and 4 s of boundaries: an end at
  // 150.45 s, before the budget.
  const int defaults[] = {200, 2000, 300, 100};
  for (int i = 0; i < 4; ++i) EXPECT_EQ(f.stages[i].iterations, defaults[i]) << f.stages[i].name;
  EXPECT_EQ(plan["scale"].get<double>(), 1.0);
  EXPECT_NEAR(plan["predicted_end_seconds"].get<double>(), 150.45, 1e-9);
}

TEST(TimeBudget, ALongerBudgetRunsTheAlbedoPassesTheStageCapCut) {
  FourStages f;
  f.stages[1].longest = 4000;  // albedo_passes asked for 4000 iterations, max_stage_iterations allowed 2000
  TimeBudget b = measured(200, f);
  const Json plan = b.plan(f.stages, 0, 11, 2.0, kAllRun);
  // The fixed stages cost 10 + 30 + 5 s at their defaults (less the 0.55 s run), the boundaries
  // 4 s; the albedo gets the rest, 198 - 4 - 44.45 = 149.55 s: 2991 iterations.
  EXPECT_EQ(f.stages[0].iterations, 200);
  EXPECT_EQ(f.stages[2].iterations, 300);
  EXPECT_EQ(f.stages[3].iterations, 100);
  EXPECT_NEAR(f.stages[1].iterations, 2991, 1);
  EXPECT_NEAR(plan["predicted_end_seconds"].get<double>(), 200, 0.05);
  // With time to spare, all 4000 and an early end.
  FourStages g;
  g.stages[1].longest = 4000;
  TimeBudget c = measured(1000, g);
  EXPECT_NEAR(c.plan(g.stages, 0, 11, 2.0, kAllRun)["predicted_end_seconds"].get<double>(), 250.45, 1e-9);
  EXPECT_EQ(g.stages[1].iterations, 4000);
}

TEST(TimeBudget, ASmallBudgetScalesEveryStageAlike) {
  FourStages f;
  TimeBudget b = measured(60, f);
  const Json plan = b.plan(f.stages, 0, 11, 2.0, kAllRun);
  // 145 s x s - 0.55 + 4 = 58: s = 0.3762 for every stage (all above their floors).
  const double s = plan["scale"].get<double>();
  EXPECT_NEAR(s, 0.3762, 0.001);
  const int defaults[] = {200, 2000, 300, 100};
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(f.stages[i].iterations, s * defaults[i], 0.5) << f.stages[i].name;
  EXPECT_NEAR(2.0 + predicted(f.stages, kAllRun), 60.0, 0.1);  // within an iteration
}

TEST(TimeBudget, ABudgetBelowTheShortestScheduleIsRefusedAtTheFirstPlan) {
  FourStages f;
  TimeBudget b = measured(10, f);
  // Floors: emission 50, albedo 100, materials 75, textures 25: 1.95 + 5 + 7.5 + 1.25 + 4 s after
  // the 2 spent, an end at 21.7 s.
  try {
    b.plan(f.stages, 0, 11, 2.0, kAllRun);
    FAIL() << "a 10 s budget was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("time budget 10 s is too short"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("end at 22 s"), std::string::npos) << e.what();
  }
}

TEST(TimeBudget, ALaterPlanThatCannotKeepTheBudgetRunsTheShortestSchedule) {
  FourStages f;
  TimeBudget b = inTheAlbedoStage(f, 5.0, 1.0, 11);  // the albedo 20x dearer than predicted
  const Json plan = b.plan(f.stages, 1, 11, 40.0, kAllRun);
  EXPECT_EQ(plan["scale"].get<double>(), 0.0);
  EXPECT_EQ(f.stages[1].iterations, 100);  // 5% of its passes
  EXPECT_EQ(f.stages[2].iterations, 75);   // 25% of their length
  EXPECT_EQ(f.stages[3].iterations, 25);
}

TEST(TimeBudget, AStageKeepsItsSettlingHalfAhead) {
  FourStages f;
  TimeBudget b = inTheAlbedoStage(f, 0.05, 0.05, 1000);
  // 1000 iterations in, with the budget spent: the stage still runs as long again, so that its
  // learning-rate decay and averages (its second half) come after what has run.
  b.plan(f.stages, 1, 1000, 60.0, kAllRun);
  EXPECT_EQ(f.stages[1].iterations, 2000);
}

TEST(TimeBudget, AConvergedStageIsNotLengthenedAndTheFitEndsBeforeTheBudget) {
  FourStages f;
  f.stages[1].longest = 4000;
  TimeBudget b = measured(200, f);
  b.plan(f.stages, 0, 11, 2.0, kAllRun);
  ASSERT_NEAR(f.stages[1].iterations, 2991, 1);
  // In the albedo stage at 0.05 s per iteration, 63 s spent: it converged after 1000 iterations
  // and settles until 2000 (as Fit::checkConvergence sets it).
  b.recordBoundary(1.0);
  for (int i = 0; i < 1000; ++i) b.recordIteration(1, 0.05);
  b.endStage(1, 2000);
  f.stages[1].iterations = 2000;
  const Json plan = b.plan(f.stages, 1, 1000, 63.0, kAllRun);
  // Planned as before it would run about 2,980: it keeps 2000, the others their defaults, and the
  // fit ends at 63 + 50 + 30 + 5 s of iterations and 3 boundaries, 49 s before the budget.
  EXPECT_EQ(f.stages[1].iterations, 2000);
  EXPECT_EQ(f.stages[2].iterations, 300);
  EXPECT_EQ(f.stages[3].iterations, 100);
  EXPECT_NEAR(plan["predicted_end_seconds"].get<double>(), 151, 1e-9);
}

TEST(TimeBudget, AStagePlannedAtItsLastIterationIsNotLengthened) {
  FourStages f;
  f.stages[0].iterations = 2;
  TimeBudget b(600, f.stages, f.drawn);
  b.recordBoundary(0.1);
  b.recordIteration(0, 0.05);
  b.recordIteration(0, 0.05);
  ASSERT_TRUE(b.due(0, f.stages[0], 2));
  b.plan(f.stages, 0, 2, 0.2, kAllRun);
  EXPECT_EQ(f.stages[0].iterations, 2);
}

TEST(TimeBudget, AStageThatWillNotRunCostsNothing) {
  FourStages with, without;
  TimeBudget a = measured(60, with), b = measured(60, without);
  a.plan(with.stages, 0, 11, 2.0, kAllRun);
  const std::vector<bool> noMaterials{true, true, false, true};
  b.plan(without.stages, 0, 11, 2.0, noMaterials);
  EXPECT_GT(without.stages[1].iterations, with.stages[1].iterations + 100);
  EXPECT_NEAR(2.0 + predicted(without.stages, noMaterials), 60.0, 0.1);
}

TEST(TimeBudget, APlanIsDueAfterAStagesFirstIterationsThenEveryTenthUpToItsHalf) {
  FourStages f;
  TimeBudget b(600, f.stages, f.drawn);
  b.recordBoundary(0.1);
  for (int i = 0; i < 10; ++i) b.recordIteration(0, 0.05);
  EXPECT_FALSE(b.due(0, f.stages[0], 10));
  b.recordIteration(0, 0.05);
  ASSERT_TRUE(b.due(0, f.stages[0], 11));
  b.plan(f.stages, 0, 11, 1.0, kAllRun);
  ASSERT_EQ(f.stages[0].iterations, 200);  // a long budget: the emission stage at its default
  EXPECT_FALSE(b.due(0, f.stages[0], 30));
  EXPECT_TRUE(b.due(0, f.stages[0], 31));  // 11 + a tenth
  b.plan(f.stages, 0, 31, 1.0, kAllRun);
  EXPECT_TRUE(b.due(0, f.stages[0], 51));
  b.plan(f.stages, 0, 91, 1.0, kAllRun);
  EXPECT_FALSE(b.due(0, f.stages[0], 111));  // in its settling half
}

TEST(TimeBudget, ACheckpointKeepsThePlanAndRefusesAnotherOne) {
  FourStages f, g;
  TimeBudget b = measured(60, f);
  b.plan(f.stages, 0, 11, 2.0, kAllRun);
  Checkpoint ck;
  double elapsed = 2.5;
  CheckpointIo out = CheckpointIo::writer(ck);
  b.serialise(out, elapsed, "ck");
  TimeBudget c(60, g.stages, g.drawn);
  double read = 0;
  CheckpointIo in = CheckpointIo::reader(ck);
  c.serialise(in, read, "ck");
  c.apply(g.stages);
  EXPECT_EQ(read, 2.5);
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(g.stages[i].iterations, f.stages[i].iterations);
  EXPECT_FALSE(c.due(0, g.stages[0], 12));  // planned already

  ck.put("budget.lengths", std::vector<int>{200, 2000, -3, 100});
  CheckpointIo bad = CheckpointIo::reader(ck);
  EXPECT_THROW(
      {
        try {
          c.serialise(bad, read, "WORK/checkpoint.bin");
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("WORK/checkpoint.bin"), std::string::npos) << e.what();
          throw;
        }
      },
      Error);
}

namespace {

// A fit whose clock advances 1/64 s per iteration and not at all between them: the plan's
// prediction is then exact (every stage draws the same texels), and sums of the clock are exact.
struct ClockedFit {
  double t = 0;
  int stopAt = 0;  // global iteration after which the fit stops (0: never)
  FitHooks hooks() {
    FitHooks h;
    h.clock = [this] { return t; };
    h.afterIteration = [this](const FitIteration& it) {
      t += 1.0 / 64;
      return stopAt == 0 || it.iteration < stopAt;
    };
    return h;
  }
};

FitConfig budgetConfig(double seconds) {
  FitConfig c;
  c.batchTexels = 256, c.framesPerTexel = 2, c.maxDepth = 3;
  c.emissionBatchTexels = 0, c.materialBatchTexels = 0;  // every iteration draws 256 texels
  c.emissionIterations = 40, c.materialIterations = 16, c.emissionTextureIterations = 12;
  c.albedoPasses = 8;
  c.checkpointEvery = 1000000;
  c.timeBudget = static_cast<float>(seconds);
  return c;
}

}  // namespace

TEST(FitTimeBudget, EndsAtTheBudgetOnItsClockAndAResumedFitKeepsThePlan) {
  const fs::path dir = smallPreparedRoom("time_budget"), work = dir / "work";
  // A budget of 2 s is 128 iterations of this clock.
  ClockedFit whole;
  const FitSummary s = runFit(work, budgetConfig(2.0), false, whole.hooks());
  EXPECT_NEAR(whole.t, 2.0, 2.0 / 64);
  EXPECT_EQ(s.iterations, static_cast<int>(std::lround(whole.t * 64)));
  const Json m = readJson(work / "result" / "materials.json");
  ASSERT_TRUE(m.contains("time_budget"));
  EXPECT_EQ(m["time_budget"]["fit_seconds"].get<double>(), whole.t);
  int planned = 0, plans = 0;
  for (const Json& stage : m["time_budget"]["iterations"]) planned += stage[1].get<int>();
  EXPECT_EQ(planned, s.iterations);
  std::ifstream metrics(work / "metrics.jsonl");
  for (std::string line; std::getline(metrics, line);) plans += Json::parse(line).contains("budget");
  EXPECT_GE(plans, 4);  // each stage after its first iterations, and the albedo's a quarter through
  const std::vector<float> uninterrupted = fittedValues(work);
  std::ifstream page(writeFitReport(work));
  const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("Time budget 2 s: the fit took 2 s"), std::string::npos);

  // The fixed schedule it replaced is far longer: the budget, not the defaults, set where it ended.
  ClockedFit fixed;
  EXPECT_GT(runFit(work, budgetConfig(0), false, fixed.hooks()).iterations, 2 * s.iterations);

  // Stopped in the albedo stage after its first plan, resumed on a clock that starts again at 0.
  fs::remove_all(work / "result");
  ClockedFit part;
  part.stopAt = 70;
  runFit(work, budgetConfig(2.0), false, part.hooks());
  ASSERT_FALSE(fs::exists(work / "result"));
  ClockedFit rest;
  const FitSummary r = runFit(work, budgetConfig(2.0), true, rest.hooks());
  EXPECT_EQ(r.iterations, s.iterations);
  EXPECT_EQ(part.t + rest.t, whole.t);
  EXPECT_TRUE(fittedValues(work) == uninterrupted) << "the resumed fit differs from the uninterrupted one";
}
