// `mpirun -np N relume fit` (core/ranks.h): the ranks split every pass's rays and exchange what they
// traced, so the fit ends bit for bit as one process does; a checkpoint written at one rank count
// resumes at another; a rank killed mid-fit ends the job, and `--resume` then ends as the
// uninterrupted run. Skipped where relume was built without MPI or mpirun is not installed.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

#include "core/ranks.h"
#include "io/image.h"
#include "io/json.h"
#include "support/file_bytes.h"
#include "support/prepared_capture.h"
#include "support/run_relume.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// What two runs of the same fit must agree on: the albedo's pixels, the scene, its lights, the
// frames' gains, and every object's fitted values (materials.json's other keys are the run's own
// memory and seconds).
void expectSameResult(const fs::path& a, const fs::path& b, const std::string& what) {
  EXPECT_EQ(readImage(a / "result" / "albedo.exr").rgb, readImage(b / "result" / "albedo.exr").rgb) << what;
  for (const char* f : {"scene.json", "lights.json", "frames.json"})
    EXPECT_TRUE(fileBytes(a / "result" / f) == fileBytes(b / "result" / f)) << f << ": " << what;
  EXPECT_EQ(readJson(a / "result" / "materials.json")["objects"], readJson(b / "result" / "materials.json")["objects"])
      << what;
}

// WORK/metrics.jsonl, line by line.
std::vector<Json> metrics(const fs::path& work) {
  std::vector<Json> lines;
  std::ifstream in(work / "metrics.jsonl");
  for (std::string line; std::getline(in, line);) lines.push_back(Json::parse(line));
  return lines;
}

class DistributedFit : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!MpiSession::available()) GTEST_SKIP() << "relume was built without MPI (install libopenmpi-dev)";
    if (std::system("command -v mpirun > /dev/null 2>&1") != 0) GTEST_SKIP() << "mpirun is not installed";
    dir_ = smallPreparedRoom(std::string("distributed_fit_") +
                             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::ofstream(dir_ / "fit.json") << R"({"batch_texels": 1024, "max_depth": 3, "emission_iterations": 40,
      "material_iterations": 20, "albedo_passes": 20, "emission_texture_iterations": 20, "checkpoint_every": 7})";
    std::ofstream(dir_ / "stop.json") << R"({"batch_texels": 1024, "max_depth": 3, "emission_iterations": 40,
      "material_iterations": 20, "albedo_passes": 20, "emission_texture_iterations": 20, "checkpoint_every": 7,
      "stop_after_iterations": 60})";
  }
  // A fresh copy of the prepared work folder, named `name`.
  fs::path work(const std::string& name) {
    const fs::path w = dir_ / name;
    fs::remove_all(w);
    fs::copy(dir_ / "work", w, fs::copy_options::recursive);
    return w;
  }
  std::string fit(const fs::path& w, const std::string& config, bool resume = false,
                  const std::string& log = "warn") const {
    return "--log " + log + " fit '" + w.string() + "' --config '" + (dir_ / config).string() + "' --no-report" +
           (resume ? " --resume" : "");
  }
  fs::path dir_;
};

}  // namespace

TEST_F(DistributedFit, TwoRanksEndAsOneProcessAndACheckpointResumesAtAnotherRankCount) {
  const fs::path one = work("one"), two = work("two"), twoThenOne = work("two_then_one"),
                 oneThenTwo = work("one_then_two");
  RelumeRun run = runRelume(fit(one, "fit.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  run = runRelumeRanks(2, fit(two, "fit.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  expectSameResult(one, two, "one process and 2 ranks");
  // Rank 0 alone writes: the metrics hold each line once, with what the ranks exchanged.
  const std::vector<Json> metricsOne = metrics(one), metricsTwo = metrics(two);
  ASSERT_EQ(metricsTwo.size(), metricsOne.size());
  for (size_t i = 0; i < metricsOne.size(); ++i)
    EXPECT_EQ(metricsTwo[i].value("loss", -1.0), metricsOne[i].value("loss", -1.0)) << "metrics line " << i;
  EXPECT_FALSE(metricsOne.back().contains("shared_bytes_per_iteration"));
  EXPECT_GT(metricsTwo.back().value("shared_bytes_per_iteration", 0.0), 0.0);

  // Stopped mid-fit at one rank count, resumed at the other.
  run = runRelumeRanks(2, fit(twoThenOne, "stop.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  ASSERT_FALSE(fs::exists(twoThenOne / "result"));
  run = runRelume(fit(twoThenOne, "fit.json", true));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  expectSameResult(one, twoThenOne, "stopped at 2 ranks, resumed as one process");
  run = runRelume(fit(oneThenTwo, "stop.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  run = runRelumeRanks(2, fit(oneThenTwo, "fit.json", true));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  expectSameResult(one, oneThenTwo, "stopped as one process, resumed at 2 ranks");

  // Ranks that read different inputs (hosts without a shared filesystem; here two configs) would
  // not fit the same thing: refused before the first iteration.
  const fs::path mixed = work("mixed");
  run = runShell(mpirunCommand(1) + " " + relumeBinary().string() + " " + fit(mixed, "fit.json") + " : -np 1 " +
                 relumeBinary().string() + " " + fit(mixed, "stop.json"));
  EXPECT_NE(run.exitCode, 0);
  EXPECT_NE(run.output.find("the MPI ranks read different work folders, configs or checkpoints"), std::string::npos)
      << run.output;
  EXPECT_FALSE(fs::exists(mixed / "checkpoint.bin"));

  // Any other command would do its work twice: refused, before it writes anything.
  run = runRelumeRanks(2, "--log warn synth --scene room --frames 2 --out '" + (dir_ / "synthesised_twice").string() +
                              "'");
  EXPECT_NE(run.exitCode, 0);
  EXPECT_NE(run.output.find("only `relume fit` and `relume prepare` split their work between MPI ranks"),
            std::string::npos)
      << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "synthesised_twice"));
}

// Three ranks, a batch of several sub-batches (so chunks are numbered from a sub-batch's first
// ray, not 0) and the crossfit pairing, whose per-ray losses are written inside the traced chunks.
TEST_F(DistributedFit, ThreeRanksWithCrossfitPairingOverSeveralSubBatchesEndAsOneProcess) {
  std::ofstream(dir_ / "crossfit.json") << R"({"batch_texels": 8192, "pairing": "crossfit", "max_depth": 3,
    "emission_iterations": 8, "material_iterations": 4, "albedo_passes": 4, "emission_texture_iterations": 4,
    "metrics_every": 1})";
  const fs::path one = work("one"), three = work("three");
  RelumeRun run = runRelume(fit(one, "crossfit.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  run = runRelumeRanks(3, fit(three, "crossfit.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  expectSameResult(one, three, "one process and 3 ranks");
  const std::vector<Json> metricsOne = metrics(one), metricsThree = metrics(three);
  const size_t lines = std::min(metricsOne.size(), metricsThree.size());
  int severalSubBatches = 0;
  for (size_t i = 0; i < lines; ++i) {
    EXPECT_EQ(metricsOne[i].value("loss", -1.0), metricsThree[i].value("loss", -1.0)) << "line " << i;
    EXPECT_GT(metricsThree[i].value("shared_bytes_per_iteration", 0.0), 0.0) << "line " << i;
    severalSubBatches += metricsOne[i].value("rays", 0) > 16384;  // a sub-batch: 64 chunks of 256 rays
  }
  EXPECT_GT(lines, 10u);
  EXPECT_GT(severalSubBatches, 0);
}

// A rank killed while the others wait for its share: the job ends with an error (not a hang), no
// result is left, and the fit resumed from the last checkpoint ends as the uninterrupted run.
TEST_F(DistributedFit, ARankKilledEndsTheJobAndTheFitResumesFromItsCheckpoint) {
  const fs::path one = work("one"), killed = work("killed");
  RelumeRun run = runRelume(fit(one, "fit.json"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  // Once rank 0 has written its first checkpoint (iteration 7 of about 230), the last of
  // mpirun's children (listed in /proc) is killed: rank 1.
  const std::string checkpoint = (killed / "checkpoint.bin").string();
  std::string script = "(";  // appended, not `"(" + ...`: GCC 12 warns falsely (-Wrestrict) on that
  script += mpirunCommand(2) + " " + relumeBinary().string() + " " + fit(killed, "fit.json") +
            " & M=$!; for i in $(seq 1200); do [ -f '" + checkpoint + "' ] && break; sleep 0.05; done;"
            " kill -KILL $(tr ' ' '\\n' < /proc/$M/task/$M/children | grep . | tail -1); wait $M)";
  run = runShell(script);
  ASSERT_NE(run.exitCode, 0) << "the fit ended before the kill, or the job went on without a rank:\n" << run.output;
  EXPECT_FALSE(fs::exists(killed / "result" / "materials.json")) << run.output;
  ASSERT_TRUE(fs::exists(killed / "checkpoint.bin")) << "nothing to resume from:\n" << run.output;
  run = runRelume(fit(killed, "fit.json", true, "info"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  EXPECT_NE(run.output.find("resumed at stage"), std::string::npos) << run.output;
  expectSameResult(one, killed, "a rank killed, then resumed");
  for (const auto& e : fs::directory_iterator(killed))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path() << " left behind";
}
