// A fit killed right after any stage boundary and resumed from the checkpoint written there ends
// exactly where the uninterrupted run ends (at one thread: the texture gradient scatter uses
// float atomics, whose order varies between threads).
#include "extremes.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <map>

#include "optim/checkpoint.h"

using namespace relume;
using namespace relume::extremes;
namespace fs = std::filesystem;

namespace {

// Keeps every stage-boundary checkpoint a fit writes, as WORK/boundary<n>.bin. The boundary
// checkpoint of stage k is WORK/checkpoint.bin when stage k + 1's first iteration ends (with
// checkpoint_every beyond every stage's length nothing overwrites it before), and the last one is
// what the fit leaves. A fit hook sees those moments exactly (watching the folder for renames
// missed one under load).
class CheckpointRecorder {
 public:
  explicit CheckpointRecorder(fs::path work) : work_(std::move(work)) {
    hooks_.afterIteration = [this](const FitIteration& it) {
      if (!stage_.empty() && it.stage != stage_) keep();
      stage_ = it.stage;
      return true;
    };
  }
  const FitHooks& hooks() const { return hooks_; }
  std::vector<fs::path> stop() {
    keep();
    return versions_;
  }

 private:
  void keep() {
    versions_.push_back(work_ / ("boundary" + std::to_string(versions_.size()) + ".bin"));
    fs::copy_file(work_ / "checkpoint.bin", versions_.back(), fs::copy_options::overwrite_existing);
  }
  fs::path work_;
  FitHooks hooks_;
  std::string stage_;
  std::vector<fs::path> versions_;
};

// Every fitted parameter, by group name (emission textures included).
std::map<std::string, std::vector<float>> fittedValues(const fs::path& work) {
  SceneDescription fit = loadSceneFile(work / "result" / "scene.json");
  std::map<std::string, std::vector<float>> v;
  for (const ParamGroup& g : paramGroups(fit.appearance)) v[g.name()].assign(g.values.begin(), g.values.end());
  return v;
}

void expectSameFit(const std::map<std::string, std::vector<float>>& resumed,
                   const std::map<std::string, std::vector<float>>& whole) {
  for (const auto& [name, values] : whole) {
    const auto r = resumed.find(name);
    if (r == resumed.end()) {
      ADD_FAILURE() << name << " is missing";
      continue;
    }
    const auto [a, b] = std::mismatch(values.begin(), values.end(), r->second.begin(), r->second.end());
    EXPECT_TRUE(a == values.end() && b == r->second.end())
        << name << " differs first at entry " << a - values.begin() << ": "
        << (a != values.end() ? std::to_string(*a) : "end") << " uninterrupted, "
        << (b != r->second.end() ? std::to_string(*b) : "end") << " resumed";
  }
  for (const auto& [name, values] : resumed) EXPECT_TRUE(whole.count(name)) << name << " only in the resumed run";
}

}  // namespace

TEST(ExtremeResume, FromEachStageBoundaryEndsBitExactAsAnUninterruptedRun) {
  // Two resolutions, so that one boundary also upsamples the albedo and its Gauss-Newton state.
  const fs::path dir = tinyCapture("resume", 4, {}, {32, 64}), work = dir / "work";
  FitConfig c = tinyFit();
  c.maxResolution = 64;
  c.checkpointEvery = 1000000;  // checkpoints at stage ends only
  tbb::task_arena one(1);       // the resumed runs on one thread, the whole one on all: bit-exact anyway
  CheckpointRecorder recorder(work);
  runFit(work, c, false, recorder.hooks());
  const std::vector<fs::path> boundaries = recorder.stop();
  const auto whole = fittedValues(work);
  expectBoundedFit(dir);
  // emission | scale_probe@32 ... scale_probe_4@32 (skipped: no light is seen only saturated) |
  // albedo@32 | emission_refit (skipped: the second light decision agrees) | materials | albedo@64 |
  // emission_texture |: each checkpoint resumes at the stage after the one it ends.
  const int resumesAt[] = {1, 6, 8, 9, 10};
  ASSERT_EQ(boundaries.size(), std::size(resumesAt));
  for (size_t k = 0; k < boundaries.size(); ++k) {
    const Checkpoint ck = Checkpoint::read(boundaries[k]);
    SCOPED_TRACE("resumed at stage " + std::to_string(ck.meta.value("stage", -1)));
    EXPECT_EQ(ck.meta.value("stage", -1), resumesAt[k]);
    EXPECT_EQ(ck.meta.value("iteration", -1), 0);
    fs::remove_all(work / "result");
    fs::copy_file(boundaries[k], work / "checkpoint.bin", fs::copy_options::overwrite_existing);
    one.execute([&] { runFit(work, c, true); });
    // Bound: bit-exact, every parameter of every group (emission textures included).
    expectSameFit(fittedValues(work), whole);
  }
}
