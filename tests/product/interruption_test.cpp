// `kill -9` at any moment of a fit, then `--resume`: the result is the uninterrupted run's, bit for
// bit; and at any moment of `prepare`, then `prepare` again: its outputs are the uninterrupted run's. Two
// kinds of moment: wall-clock times, where a kill lands mid-iteration, mid-checkpoint or mid-result as it
// happens; and the kill points of core/kill_point.h, which stop a run inside a checkpoint, a result or any
// file being written. Whatever a kill hits, the resumed result must not differ.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include <sys/wait.h>

#include "io/image.h"
#include "io/json.h"
#include "scenes/synth.h"
#include "support/file_bytes.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path relumeBinary() { return fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "relume"; }

// How a run of relume is interrupted: not at all, SIGKILL after `seconds`, or at a kill point
// ("<point>:<pass>", core/kill_point.h).
struct Kill {
  double seconds = 0;
  std::string at;
};

// Runs relume with `arguments`, interrupted as `kill` says; returns std::system's status.
int run(const std::string& arguments, const Kill& kill) {
  std::string command;
  if (!kill.at.empty()) command += "RELUME_KILL_AT=" + kill.at + " ";
  if (kill.seconds > 0) command += "timeout -s KILL " + std::to_string(kill.seconds) + " ";
  command += fmt::format("'{}' --log warn {} > /dev/null 2>&1", relumeBinary().string(), arguments);
  return std::system(command.c_str());
}

int fit(const fs::path& work, const fs::path& config, bool resume, const Kill& kill = {}) {
  return run("fit '" + work.string() + "' --config '" + config.string() + "' --no-report" + (resume ? " --resume" : ""),
             kill);
}

// `relume prepare CAPTURE --out WORK` at one resolution.
int prepare(const fs::path& capture, const fs::path& work, const Kill& kill = {}) {
  return run("prepare '" + capture.string() + "' --out '" + work.string() + "' --res 256 --gutter-res 256", kill);
}

// Whether std::system's `status` is that of a command killed by SIGKILL (the shell may report it
// as exit status 128 + 9).
bool killed(int status) {
  return (WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) || (WIFEXITED(status) && WEXITSTATUS(status) == 137);
}

// The temporaries of writeAtomically in `dir`: ".<stem>.tmp<pid><extension>".
std::vector<std::string> temporaries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (name[0] == '.' && name.find(".tmp") != std::string::npos) names.push_back(name);
  }
  return names;
}

// prepare.json without what differs between any two runs: the seconds and the peak memories.
Json withoutTimes(Json j) {
  if (j.is_object()) {
    for (auto it = j.begin(); it != j.end();)
      if (it.key().find("seconds") != std::string::npos || it.key().rfind("peak_rss_mib", 0) == 0)
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
// run's (content() above), and no other file is left behind. Killed at wall-clock moments, then as
// each of its files is written in full but not yet renamed over its name (kill point atomic-write).
TEST(Interruption, KilledPreparesRerunToTheUninterruptedOutputs) {
  SynthCaptureOptions so;
  so.frames = 24, so.testFrames = 1, so.width = 128, so.height = 96, so.spp = 2, so.testSpp = 2;
  so.atlasResolution = 256;
  so.imperfections = parseImperfections("segmentation=none");  // the segmentation phase runs too
  so.out = fs::temp_directory_path() / "relume_interruption_prepare" / "capture";
  fs::remove_all(so.out.parent_path());
  writeSynthCapture(so);
  const fs::path reference = so.out.parent_path() / "reference", work = so.out.parent_path() / "work";
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(prepare(so.out, reference), 0);
  const double runSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::map<std::string, std::string> whole;
  for (const auto& e : fs::directory_iterator(reference)) whole[e.path().filename().string()] = content(e.path());
  ASSERT_TRUE(whole.count("frames.bin") && whole.count("visibility.bin") && whole.count("albedo_init.exr") &&
              whole.count("segments.bin") && whole.count("objects.json"));

  // Killed as `kill` says, then run again; false if the run ended before the kill.
  auto killThenRerun = [&](const Kill& kill, const std::string& moment) {
    fs::remove_all(work);
    const int status = prepare(so.out, work, kill);
    if (status == 0) return false;
    EXPECT_TRUE(killed(status)) << "status " << status << ", killed at " << moment;
    if (!kill.at.empty()) {
      EXPECT_EQ(temporaries(work).size(), 1u) << "killed at " << moment;
    }
    EXPECT_EQ(prepare(so.out, work), 0) << "after a kill at " << moment;
    std::map<std::string, std::string> again;
    for (const auto& e : fs::directory_iterator(work)) again[e.path().filename().string()] = content(e.path());
    for (const auto& [name, bytes] : whole)
      EXPECT_TRUE(again.count(name) && again[name] == bytes) << name << ", killed at " << moment;
    for (const auto& [name, bytes] : again) EXPECT_TRUE(whole.count(name)) << name << " left over, killed at " << moment;
    return true;
  };
  int kills = 0;
  for (const double fraction : {0.05, 0.15, 0.3, 0.45, 0.6, 0.75, 0.9})
    kills += killThenRerun({fraction * runSeconds, ""}, std::to_string(fraction * runSeconds) + " s");
  EXPECT_GE(kills, 4) << "the run took " << runSeconds << " s; most kills came after it ended";

  int writes = 0;
  while (writes < 50 && killThenRerun({0, "atomic-write:" + std::to_string(writes + 1)}, "atomic write " +
                                                                                           std::to_string(writes + 1)))
    ++writes;
  EXPECT_GE(writes, 4) << "prepare writes frames.bin, visibility.bin, albedo_init.exr and prepare.json";
  EXPECT_LT(writes, 50) << "every run was killed: the kill point is not where prepare's writes end";
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
    // Resumed until it ends (a kill so late that the run finished is a run to compare as well).
    if (fit(dir / "work", config, false, {seconds, ""}) != 0) {
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

// Killed inside the writes themselves (core/kill_point.h): a checkpoint half written, with no
// earlier one and with one to fall back on; a checkpoint written but not renamed over the last; a
// result half staged; a result staged in full after the previous one was removed. Each kill leaves
// its partial file; `--resume` must neither take it for a complete one nor leave it behind.
TEST(Interruption, FitsKilledMidWriteResumeToTheUninterruptedResult) {
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 4, so.testSpp = 4;
  so.atlasResolution = 128;
  const fs::path dir = preparedCapture("interruption_points", so, 128), work = dir / "work";
  const fs::path config = dir / "fit.json";
  std::ofstream(config) << R"({"batch_texels": 1024, "max_depth": 3, "emission_iterations": 40,
    "material_iterations": 20, "albedo_passes": 20, "emission_texture_iterations": 20, "checkpoint_every": 7})";
  ASSERT_EQ(fit(work, config, false), 0);
  const Image whole = readImage(work / "result" / "albedo.exr");
  const Json wholeMaterials = readJson(work / "result" / "materials.json");

  const int misspelt = fit(work, config, false, {0, "checkpoint-half:0"});
  EXPECT_TRUE(WIFEXITED(misspelt) && WEXITSTATUS(misspelt) == 1) << "a kill point asked for at pass 0: " << misspelt;

  for (const std::string at : {"checkpoint-half:1", "checkpoint-half:3", "atomic-write:2", "result-half:1",
                               "result-staged:1"}) {
    fs::remove_all(work / "result");
    fs::remove(work / "checkpoint.bin");
    ASSERT_TRUE(killed(fit(work, config, false, {0, at}))) << at;
    if (at.rfind("result", 0) == 0) {
      EXPECT_TRUE(temporaries(work).empty()) << at;
      EXPECT_FALSE(fs::exists(work / "result")) << at;
      EXPECT_TRUE(fs::exists(work / "result.partial" / "albedo.exr")) << at;
      EXPECT_EQ(fs::exists(work / "result.partial" / "materials.json"), at == "result-staged:1") << at;
    } else {
      EXPECT_EQ(temporaries(work).size(), 1u) << at << ": the checkpoint being written";
      EXPECT_EQ(fs::exists(work / "checkpoint.bin"), at != "checkpoint-half:1") << at;
    }
    ASSERT_EQ(fit(work, config, true), 0) << "after a kill at " << at;
    EXPECT_TRUE(temporaries(work).empty()) << at;
    EXPECT_FALSE(fs::exists(work / "result.partial")) << at;
    EXPECT_EQ(readImage(work / "result" / "albedo.exr").rgb, whole.rgb) << "killed at " << at;
    EXPECT_EQ(readJson(work / "result" / "materials.json")["objects"], wholeMaterials["objects"]) << "killed at " << at;
  }
}
