// `mpirun -np N relume prepare` (docs/design/distributed.md): the frames are decoded and the init's
// texel rows observed by the ranks in turn, the other phases run on the root, and the work folder
// ends byte for byte as one process writes it; a rank that fails ends the job and leaves no frame
// cache. Skipped where relume was built without MPI or mpirun is not installed.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "core/ranks.h"
#include "io/json.h"
#include "scenes/imperfections.h"
#include "scenes/synth.h"
#include "support/file_bytes.h"
#include "support/run_relume.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// prepare.json without what differs between any two runs: seconds and resident memory.
Json withoutTimings(const Json& j) {
  if (j.is_array()) {
    Json out = Json::array();
    for (const Json& v : j) out.push_back(withoutTimings(v));
    return out;
  }
  if (!j.is_object()) return j;
  Json out = Json::object();
  for (const auto& [key, value] : j.items())
    if (key.find("seconds") == std::string::npos && key.find("peak_rss") == std::string::npos)
      out[key] = withoutTimings(value);
  return out;
}

class DistributedPrepare : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!MpiSession::available()) GTEST_SKIP() << "relume was built without MPI (install libopenmpi-dev)";
    if (std::system("command -v mpirun > /dev/null 2>&1") != 0) GTEST_SKIP() << "mpirun is not installed";
    dir_ = fs::temp_directory_path() /
           (std::string("relume_distributed_prepare_") + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    // 8-bit bracketed frames (clipped pixels, the frames' statistics) and a mesh without objects
    // (the computed segmentation, on the root).
    SynthCaptureOptions so;
    so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 2, so.testSpp = 2;
    so.imperfections = parseImperfections("bracket=-1.5,0,1.5;ldr=8;segmentation=none");
    so.out = dir_ / "capture";
    writeSynthCapture(so);
  }
  // 480^2 in 32-texel tiles: 3 ranks split each tile's 32 texel rows unevenly (11, 11, 10).
  std::string prepare(const std::string& out, const std::string& log = "warn") const {
    return "--log " + log + " prepare '" + (dir_ / "capture").string() + "' --out '" + (dir_ / out).string() +
           "' --res 480 --gutter-res 480 --tile 32";
  }
  fs::path dir_;
};

}  // namespace

TEST_F(DistributedPrepare, RanksWriteTheWorkFolderOneProcessWritesAndFindItUpToDate) {
  RelumeRun run = runRelume(prepare("one"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  for (const int ranks : {2, 3}) {
    const std::string name = std::to_string(ranks) + "_ranks";
    run = runRelumeRanks(ranks, prepare(name));
    ASSERT_EQ(run.exitCode, 0) << run.output;
    const fs::path one = dir_ / "one", many = dir_ / name;
    size_t files = 0;
    for (const auto& e : fs::directory_iterator(one)) {
      const std::string file = e.path().filename().string();
      ASSERT_TRUE(fs::exists(many / file)) << file << " missing at " << ranks << " ranks";
      if (file == "prepare.json") continue;
      EXPECT_TRUE(fileBytes(one / file) == fileBytes(many / file)) << file << " differs at " << ranks << " ranks";
      ++files;
    }
    EXPECT_GE(files, 10u);  // frames, segments, objects, atlas, visibility, init, coverage, agreement, gains
    EXPECT_EQ(withoutTimings(readJson(one / "prepare.json")), withoutTimings(readJson(many / "prepare.json")))
        << ranks << " ranks";
    for (const auto& e : fs::directory_iterator(many))
      EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path() << " left behind";
  }
  ASSERT_TRUE(readJson(dir_ / "one" / "prepare.json").at("phases").contains("segmentation"));

  // Prepared by 3 ranks, found up to date by 2: nothing is redone or rewritten.
  const std::string before = fileBytes(dir_ / "3_ranks" / "prepare.json");
  run = runRelumeRanks(2, prepare("3_ranks", "info"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  for (const char* phase : {"frames", "segmentation", "atlas", "visibility", "init"})
    EXPECT_NE(run.output.find(std::string("prepare: ") + phase + " is up to date"), std::string::npos)
        << phase << "\n" << run.output;
  EXPECT_EQ(fileBytes(dir_ / "3_ranks" / "prepare.json"), before);
}

// Frame 1 is decoded by rank 1 of 2: its unreadable image ends the whole job with the file named
// and no frame cache; the next run, with the image back, removes what the ended one left.
TEST_F(DistributedPrepare, AFrameOneRankCannotReadEndsTheJob) {
  const Json transforms = readJson(dir_ / "capture" / "transforms.json");
  const fs::path image = dir_ / "capture" / transforms.at("frames").at(1).at("file_path").get<std::string>();
  ASSERT_TRUE(fs::exists(image)) << image;
  const std::string bytes = fileBytes(image);
  std::ofstream(image, std::ios::binary | std::ios::trunc) << "not an image";
  RelumeRun run = runRelumeRanks(2, prepare("failed"));
  EXPECT_NE(run.exitCode, 0);
  EXPECT_NE(run.output.find(image.filename().string()), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "failed" / "frames.bin"));
  std::ofstream(image, std::ios::binary | std::ios::trunc) << bytes;
  run = runRelumeRanks(2, prepare("failed"));
  ASSERT_EQ(run.exitCode, 0) << run.output;
  for (const auto& e : fs::directory_iterator(dir_ / "failed"))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path() << " left behind";
}
