#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "lab/bench.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

// `relume bench` on a tiny capture: the baseline and a sweep's other values, each with an
// error-vs-time curve against the capture's ground truth, and nothing written to the work folder.
TEST(Bench, SweepsOneSettingAgainstTheBaselineWithErrorCurves) {
  const fs::path dir = smallPreparedRoom("bench");
  BenchOptions o;
  o.work = dir / "work";
  o.out = dir / "bench";
  o.sweeps = {"depth"};
  o.base.batchTexels = 512;
  o.base.maxDepth = 4;
  // 40 emission iterations: at 10 the emission stage is far from converged (on the demo's capture
  // it finds neither light, with or without emission_batch_texels, and the albedo makes up for
  // whatever emits instead); at 40 both lights are found.
  o.base.emissionIterations = 40, o.base.materialIterations = 5, o.base.albedoPasses = 4;
  o.base.maxResolution = 0;
  o.evaluateEvery = 5;
  o.testSpp = 2;
  const std::vector<BenchRun> runs = runBench(o);
  ASSERT_EQ(runs.size(), 3u);  // baseline (depth 4), then depth 2 and 9
  EXPECT_EQ(runs[0].sweep, "baseline");
  EXPECT_EQ(runs[1].value, "2");
  EXPECT_EQ(runs[2].value, "9");
  for (const BenchRun& r : runs) {
    EXPECT_GT(r.seconds, 0);
    EXPECT_TRUE(std::isfinite(r.albedoMae) && r.albedoMae > 0 && r.albedoMae < 0.5) << r.albedoMae;
    EXPECT_TRUE(std::isfinite(r.psnr)) << r.psnr;
    EXPECT_GT(r.cpuSeconds, 0);
    ASSERT_GE(r.curveCpuSeconds.size(), 3u);
    EXPECT_TRUE(std::is_sorted(r.curveCpuSeconds.begin(), r.curveCpuSeconds.end()));
    EXPECT_EQ(r.curveMae.back(), r.albedoMae);  // the curve ends at the final result
    EXPECT_GT(r.memoryMiB, 0);
  }
  EXPECT_EQ(runs[0].maeAtBaselineCost, runs[0].albedoMae);
  EXPECT_GT(runs[2].cpuSeconds, runs[1].cpuSeconds);  // depth 9 costs more than depth 2
  std::ifstream mdFile(o.out / "bench.md");
  const std::string md((std::istreambuf_iterator<char>(mdFile)), {});
  EXPECT_NE(md.find("| 4 (baseline) |"), std::string::npos) << md;
  EXPECT_TRUE(fs::exists(o.out / "depth.svg"));
  std::ifstream csv(o.out / "bench.csv");
  EXPECT_EQ(std::count(std::istreambuf_iterator<char>(csv), {}, '\n'), 4);  // header + 3 runs
  for (const char* f : {"metrics.jsonl", "checkpoint.bin", "result"}) EXPECT_FALSE(fs::exists(o.work / f)) << f;
  o.sweeps = {"colour"};
  EXPECT_THROW(runBench(o), Error);
}
