// A filesystem failure at an input path (here a symlink loop) is an input error naming the path and
// the reason, ending `relume` with the input-error exit code; never "internal error".
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/error.h"
#include "product/prepare.h"
#include "scenes/synth.h"
#include "support/run_relume.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

constexpr int kInputErrorExit = 1;  // src/cli/main.cpp

// A 2-frame 16x16 Cornell box capture in a fresh folder DIR/capture.
fs::path smallCapture(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("relume_input_paths_" + name);
  fs::remove_all(dir);
  SynthCaptureOptions so;
  so.kind = SynthSceneKind::Cornell;
  so.out = dir / "capture";
  so.frames = 2, so.testFrames = 1, so.width = so.height = 16, so.spp = 1, so.testSpp = 1, so.atlasResolution = 64;
  writeSynthCapture(so);
  return dir;
}

// Replaces `file` by a symlink to itself: every access fails with ELOOP.
void makeSymlinkLoop(const fs::path& file) {
  fs::remove(file);
  fs::create_symlink(file.filename(), file);
}

void expectInputErrorNaming(const fs::path& capture, const fs::path& work, const std::string& named) {
  const RelumeRun run =
      runRelume("prepare '" + capture.string() + "' --out '" + work.string() + "' --res 64 --gutter-res 64");
  EXPECT_EQ(run.exitCode, kInputErrorExit) << run.output;
  EXPECT_EQ(run.output.find("internal error"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find(named), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("symbolic links"), std::string::npos) << run.output;  // the reason (ELOOP)
}

}  // namespace

TEST(InputPaths, SymlinkLoopAtObjectsJsonIsAnInputError) {
  const fs::path dir = smallCapture("objects");
  makeSymlinkLoop(dir / "capture" / "objects.json");
  expectInputErrorNaming(dir / "capture", dir / "work", (dir / "capture" / "objects.json").string());
  fs::remove_all(dir);
}

TEST(InputPaths, SymlinkLoopAtMeshIsAnInputError) {
  const fs::path dir = smallCapture("mesh");
  makeSymlinkLoop(dir / "capture" / "mesh.ply");
  expectInputErrorNaming(dir / "capture", dir / "work", (dir / "capture" / "mesh.ply").string());
  fs::remove_all(dir);
}

TEST(InputPaths, SymlinkLoopAtAnImageIsAnInputError) {
  const fs::path dir = smallCapture("image");
  makeSymlinkLoop(dir / "capture" / "images" / "frame_0001.exr");
  expectInputErrorNaming(dir / "capture", dir / "work", (dir / "capture" / "images" / "frame_0001.exr").string());
  fs::remove_all(dir);
}

// Through the library: the command line checks the folder itself before prepare runs.
TEST(InputPaths, SymlinkLoopAtTheCaptureFolderIsAnInputError) {
  const fs::path dir = fs::temp_directory_path() / "relume_input_paths_folder";
  fs::remove_all(dir);
  fs::create_directories(dir);
  makeSymlinkLoop(dir / "capture");
  try {
    prepareCapture(dir / "capture", dir / "work", PrepareOptions{});
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find((dir / "capture").string()), std::string::npos) << what;
    EXPECT_NE(what.find("symbolic links"), std::string::npos) << what;
  }
  fs::remove_all(dir);
}
