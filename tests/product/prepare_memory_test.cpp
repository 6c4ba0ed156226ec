#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "io/json.h"
#include "product/prepare_memory.h"
#include "sampling/median_sketch.h"
#include "scenes/synth.h"
#include "support/file_bytes.h"
#include "support/run_relume.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

constexpr double kMiB = 1 << 20;

// A 1024^2 init phase in 32 rows of 32-texel tiles, 100 MiB held, 10 MiB of frames.
InitPhaseSize aCapture() {
  InitPhaseSize s;
  s.heldBytes = 100 * kMiB;
  s.frameCacheBytes = 10 * kMiB;
  s.resolution = 1024;
  s.tileRows = 32;
  s.tileTexels = 32;
  s.visibilityEntries = 1000;
  s.sampleObservationsAtStride1 = 50e6;
  s.defaultGainStride = 16;
  s.keptFrames = 100;
  return s;
}

}  // namespace

// Worked by hand: fixed = 100 + 10 MiB + 1000 entries x (128 + 8) B; at one band the median pass
// is 52 + 223 B per texel (275 MiB), the sample 28 B per texel + 48 B per sampled texel + 50e6 / 16
// x 24 B + 2 x 8 x 100^2 (102.7 MiB), the agreement 88 MiB.
TEST(PrepareMemory, TakesBandsThenASparserSampleAndRefusesBelowTheLeanest) {
  const InitPhaseSize s = aCapture();
  const double texels = 1024.0 * 1024.0, fixed = 110 * kMiB + 1000 * 136.0;
  const InitPhasePlan free = planInitPhase(0, s);
  EXPECT_EQ(free.bands, 1);
  EXPECT_EQ(free.gainStride, 16u);
  EXPECT_NEAR(free.fixedBytes, fixed, 1);
  EXPECT_NEAR(free.medianPassBytes, (52 + MedianSketch::kBytesPerTexel) * texels, 1);
  EXPECT_NEAR(free.samplePassBytes, 28 * texels + texels / 16 * 48 + 50e6 / 16 * 24 + 2 * 8 * 1e4, 1);
  EXPECT_NEAR(free.agreementPassBytes, 88 * texels, 1);
  EXPECT_NEAR(free.peakBytes(), fixed + free.medianPassBytes, 1);

  // Room for the median in 4 bands (52 + 223 / 4 B per texel: 107.8 MiB) but not in 2 (163.5).
  // 32 tile rows in 4 bands: 8 rows each.
  const double four = (fixed + (52 + MedianSketch::kBytesPerTexel / 4) * texels) / 0.95 + kMiB;
  const InitPhasePlan banded = planInitPhase(four, s);
  EXPECT_EQ(banded.bands, 4);
  EXPECT_EQ(banded.rowsPerBand, 8);
  EXPECT_EQ(banded.gainStride, 16u);
  EXPECT_LE(banded.peakBytes(), 0.95 * four);

  // A sample 8x larger is over every band's median: the sample thins to 4x the stride (its pass
  // then 28 B per texel + 48 B per sampled texel + 8 x 50e6 / 64 x 24 B, 28 + 0.75 + 143 MiB), and
  // the median takes what is left.
  InitPhaseSize dense = s;
  dense.sampleObservationsAtStride1 = 8 * 50e6;
  const double thin = (fixed + 28 * texels + texels / 64 * 48 + 8 * 50e6 / 64 * 24 + 2 * 8 * 1e4) / 0.95 + kMiB;
  const InitPhasePlan thinned = planInitPhase(thin, dense);
  EXPECT_EQ(thinned.gainStride, 64u);
  EXPECT_EQ(thinned.bands, 2);  // 163.5 MiB of median fits beside 172 of sample; 275 does not
  EXPECT_LE(thinned.peakBytes(), 0.95 * thin);

  // Below the leanest plan (the agreement's 88 MiB above what is held): refused, with the figure.
  try {
    planInitPhase(fixed + 80 * kMiB, s);
    FAIL() << "a budget below the leanest plan was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("needs"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("frame cache"), std::string::npos) << e.what();
  }
  // And before any work: a 1M-triangle mesh needs 135 MiB + 300 MB to be charted.
  EXPECT_THROW(checkPrepareBudgetUpFront(400 * kMiB, 1000000, 0, 64 * 64), Error);
  EXPECT_NO_THROW(checkPrepareBudgetUpFront(500 * kMiB, 1000000, 0, 64 * 64));
}

// The same capture prepared under a budget too large to change anything and under one that needs
// the median in bands: the same files, the process's peak within the budget; and refused before
// any work below its need.
TEST(PrepareMemoryBudget, BandsGiveTheSameFilesAndTheRunStaysWithinItsBudget) {
  const fs::path dir = fs::temp_directory_path() / "relume_prepare_memory_budget";
  fs::remove_all(dir);
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 2, so.testSpp = 2;
  so.out = dir / "capture";
  writeSynthCapture(so);
  // 480^2 in 32-texel tiles: 15 tile rows, so every split into bands leaves a shorter last one.
  const std::string prepare = "--log info prepare " + so.out.string() + " --res 480 --gutter-res 480 --tile 32";

  RelumeRun run = runRelume(prepare + " --out " + (dir / "whole").string() + " --memory-budget 100G");
  ASSERT_EQ(run.exitCode, 0) << run.output;
  const Json whole = readJson(dir / "whole" / "prepare.json").at("phases").at("init").at("memory_budget");
  EXPECT_EQ(whole.at("median_bands"), 1);
  const double texels = 480.0 * 480.0, sketch = MedianSketch::kBytesPerTexel * texels;
  // Half the sketch short of one band's peak, with 2 MiB for what the process holds differently.
  const double budget = (whole.at("predicted_peak_bytes").get<double>() - sketch / 2 + 2 * kMiB) / 0.95;
  ASSERT_GT(whole.at("median_pass_bytes").get<double>() - sketch / 2,
            std::max(whole.at("sample_pass_bytes").get<double>(), whole.at("agreement_pass_bytes").get<double>()));

  run = runRelume(prepare + " --out " + (dir / "banded").string() +
                  " --memory-budget " + std::to_string(static_cast<long>(budget)));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  const Json report = readJson(dir / "banded" / "prepare.json");
  const Json banded = report.at("phases").at("init").at("memory_budget");
  EXPECT_GE(banded.at("median_bands").get<int>(), 2);
  EXPECT_EQ(banded.at("gain_sample_stride"), whole.at("gain_sample_stride"));
  EXPECT_EQ(banded.at("median_bands").get<int>(),
            (15 + banded.at("tile_rows_per_band").get<int>() - 1) / banded.at("tile_rows_per_band").get<int>());
  EXPECT_NE(15 % banded.at("tile_rows_per_band").get<int>(), 0) << "the last band is as long as the others";
#ifndef __SANITIZE_ADDRESS__  // AddressSanitizer's redzones and quarantine are not in the model
  EXPECT_LE(report.at("peak_rss_mib").get<double>() * kMiB, budget);
#endif
  for (const char* file : {"albedo_init.exr", "coverage.exr", "agreement.exr", "frame_gains.json"})
    EXPECT_TRUE(fileBytes(dir / "banded" / file) == fileBytes(dir / "whole" / file)) << file << " differs";

  run = runRelume(prepare + " --out " + (dir / "refused").string() + " --memory-budget 100M");
  EXPECT_NE(run.exitCode, 0);
  EXPECT_NE(run.output.find("--memory-budget 100 MiB is too small"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(dir / "refused" / "frames.bin"));
}
