// `kill -9` at any moment of a fit, then `--resume`: the result is the uninterrupted run's, bit for
// bit. The moments are wall-clock times, so a kill lands mid-iteration, mid-checkpoint or
// mid-result as it happens; whatever it hits, the resumed result must not differ.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>

#include "io/image.h"
#include "io/json.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path relumeBinary() { return fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "relume"; }

// Runs `relume fit` on WORK, killed with SIGKILL after `seconds` when > 0; returns the exit status.
int fit(const fs::path& work, const fs::path& config, bool resume, double seconds = 0) {
  std::string command = "'" + relumeBinary().string() + "' --log warn fit '" + work.string() + "' --config '" +
                        config.string() + "' --no-report" + (resume ? " --resume" : "");
  if (seconds > 0) command = "timeout -s KILL " + std::to_string(seconds) + " " + command;
  return std::system((command + " > /dev/null 2>&1").c_str());
}

}  // namespace

TEST(Interruption, KilledFitsResumeToTheUninterruptedResult) {
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 4, so.testSpp = 4;
  so.atlasResolution = 128;
  const fs::path dir = preparedCapture("interruption", so, 128);
  const fs::path config = dir / "fit.json";
  std::ofstream(config) << R"({"batch_texels": 1024, "max_depth": 3, "emission_iterations": 40,
    "material_iterations": 20, "albedo_passes": 20, "emission_texture_iterations": 20, "checkpoint_every": 7})";
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(fit(dir / "work", config, false), 0);
  const double runSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const Image whole = readImage(dir / "work" / "result" / "albedo.exr");
  const Json wholeMaterials = readJson(dir / "work" / "result" / "materials.json");

  // Moments spread over the whole run, from its first iterations to its last writes.
  int kills = 0;
  for (const double fraction : {0.08, 0.3, 0.55, 0.8, 0.95}) {
    const double seconds = fraction * runSeconds;
    fs::remove_all(dir / "work" / "result");
    fs::remove(dir / "work" / "checkpoint.bin");
    const int killed = fit(dir / "work", config, false, seconds);
    // Resumed until it ends (a kill so late that the run finished is a run to compare as well).
    if (killed != 0) {
      ++kills;
      ASSERT_FALSE(fs::exists(dir / "work" / "result.partial" / "materials.json") &&
                   !fs::exists(dir / "work" / "checkpoint.bin"))
          << "a result was being written with no checkpoint to resume from";
      ASSERT_EQ(fit(dir / "work", config, true), 0) << "after a kill at " << seconds << " s";
    }
    EXPECT_EQ(readImage(dir / "work" / "result" / "albedo.exr").rgb, whole.rgb) << "killed at " << seconds << " s";
    EXPECT_EQ(readJson(dir / "work" / "result" / "materials.json")["objects"], wholeMaterials["objects"])
        << "killed at " << seconds << " s";
  }
  EXPECT_GE(kills, 3) << "the run took " << runSeconds << " s; most kills came after it ended";
}
