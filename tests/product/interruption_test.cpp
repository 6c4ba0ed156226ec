// `kill -9` at any moment of a fit, then `--resume`: the result is the uninterrupted run's, bit for
// bit; and at any moment of `prepare`, then `prepare` again: its outputs are the uninterrupted run's. The moments are
// wall-clock times, so a kill lands mid-iteration, mid-checkpoint or mid-result as it happens; whatever it hits, the
// resumed result must not differ.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <map>

#include "io/image.h"
#include "io/json.h"
#include "scenes/synth.h"
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

// Runs `relume prepare CAPTURE --out WORK` at one resolution, killed as above; returns the status.
int prepare(const fs::path& capture, const fs::path& work, double seconds = 0) {
  std::string command = "'" + relumeBinary().string() + "' --log warn prepare '" + capture.string() + "' --out '" +
                        work.string() + "' --res 256 --gutter-res 256";
  if (seconds > 0) command = "timeout -s KILL " + std::to_string(seconds) + " " + command;
  return std::system((command + " > /dev/null 2>&1").c_str());
}

std::string fileBytes(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// prepare.json without what differs between any two runs: the seconds and the peak memory.
Json withoutTimes(Json j) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end();)
      if (it.key().find("seconds") != std::string::npos || it.key() == "peak_rss_mib")
        it = j.erase(it);
      else
        *it = withoutTimes(*it), ++it;
  }
  return j;
}

// A prepared file's content as two runs agree on it: an EXR's pixels (its header holds the time of
// writing), prepare.json without the seconds and the peak memory, any other file's bytes.
std::string content(const fs::path& f) {
  if (f.extension() == ".exr") {
    const Image image = readImage(f);
    return std::string(reinterpret_cast<const char*>(image.rgb.data()), image.rgb.size() * sizeof(float));
  }
  return f.filename() == "prepare.json" ? withoutTimes(readJson(f)).dump() : fileBytes(f);
}

}  // namespace

// The same for `prepare`: killed anywhere, run again, every file it leaves is the uninterrupted
// run's (content() above), and no other file is left behind.
TEST(Interruption, KilledPreparesRerunToTheUninterruptedOutputs) {
  SynthCaptureOptions so;
  so.frames = 24, so.testFrames = 1, so.width = 128, so.height = 96, so.spp = 2, so.testSpp = 2;
  so.atlasResolution = 256;
  so.out = fs::temp_directory_path() / "relume_interruption_prepare" / "capture";
  fs::remove_all(so.out.parent_path());
  writeSynthCapture(so);
  const fs::path reference = so.out.parent_path() / "reference", work = so.out.parent_path() / "work";
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(prepare(so.out, reference), 0);
  const double runSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::map<std::string, std::string> whole;
  for (const auto& e : fs::directory_iterator(reference)) whole[e.path().filename().string()] = content(e.path());
  ASSERT_TRUE(whole.count("frames.bin") && whole.count("visibility.bin") && whole.count("albedo_init.exr"));

  int kills = 0;
  for (const double fraction : {0.05, 0.15, 0.3, 0.45, 0.6, 0.75, 0.9}) {
    const double seconds = fraction * runSeconds;
    fs::remove_all(work);
    if (prepare(so.out, work, seconds) == 0) continue;  // finished before the kill
    ++kills;
    ASSERT_EQ(prepare(so.out, work), 0) << "after a kill at " << seconds << " s";
    std::map<std::string, std::string> again;
    for (const auto& e : fs::directory_iterator(work)) again[e.path().filename().string()] = content(e.path());
    for (const auto& [name, bytes] : whole)
      EXPECT_TRUE(again.count(name) && again[name] == bytes) << name << ", killed at " << seconds << " s";
    for (const auto& [name, bytes] : again)
      EXPECT_TRUE(whole.count(name)) << name << " left over, killed at " << seconds << " s";
  }
  EXPECT_GE(kills, 4) << "the run took " << runSeconds << " s; most kills came after it ended";
}

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
