#include <gtest/gtest.h>

#include "pipeline/profile.h"
#include "prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

// `profile --what fit`: times the asked stage's iterations of a real fit and leaves the work
// folder as it was.
TEST(ProfileFit, TimesTheAskedStageAndWritesNothing) {
  const fs::path dir = smallPreparedRoom("profile_fit");
  const fs::path work = dir / "work";
  FitConfig c;
  c.batchTexels = 512;
  c.maxDepth = 3;
  c.emissionIterations = 4;
  const FitProfile p = profileFit(work, c, "albedo", 3);
  EXPECT_EQ(p.stage, "albedo@128");
  ASSERT_EQ(p.perIteration.size(), 3u);
  for (const FitPhaseTimes& t : p.perIteration) {
    EXPECT_GT(t.sample, 0);
    EXPECT_GT(t.primal, 0);
    EXPECT_GT(t.adjoint, 0);
    EXPECT_GT(t.optimiser, 0);  // the albedo steps in this stage
  }
  ASSERT_GT(p.raysPerIteration, 0u);
  EXPECT_GE(p.primalClosestRays, p.raysPerIteration);  // every path traces at least its camera ray
  EXPECT_GT(p.primalTraceOnly, 0);
  EXPECT_GT(p.adjointNoScatter, 0);
  // The albedo at 128^2 (RGB floats) is among the parameters the fit holds, and its state with it.
  EXPECT_GE(p.memory["parameters"].get<double>(), 128.0 * 128 * 3 * 4);
  EXPECT_GE(p.memory["optimiser_state"].get<double>(), 128.0 * 128 * 3 * 4);
  EXPECT_GT(p.memory["total"].get<double>(), p.memory["parameters"].get<double>());
  for (const char* f : {"metrics.jsonl", "checkpoint.bin", "result"}) EXPECT_FALSE(fs::exists(work / f)) << f;
  EXPECT_THROW(profileFit(work, c, "no-such-stage", 1), Error);
}
