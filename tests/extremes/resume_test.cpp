// A fit killed right after any stage boundary and resumed from the checkpoint written there ends
// exactly where the uninterrupted run ends (at one thread: the texture gradient scatter uses
// float atomics, whose order varies between threads).
#include "extremes.h"

#include <poll.h>
#include <sys/inotify.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <thread>

#include "optim/checkpoint.h"

using namespace relume;
using namespace relume::extremes;
namespace fs = std::filesystem;

namespace {

// Keeps every version of WORK/checkpoint.bin a fit writes, as WORK/boundary<n>.bin: a hard link to
// each new file as it is renamed into place (checkpoints are written atomically). With
// checkpoint_every beyond every stage's length, those are exactly the stage-boundary checkpoints,
// at least one iteration apart, while a link takes microseconds.
class CheckpointRecorder {
 public:
  explicit CheckpointRecorder(fs::path work) : work_(std::move(work)), fd_(inotify_init1(IN_NONBLOCK)) {
    EXPECT_GE(inotify_add_watch(fd_, work_.c_str(), IN_MOVED_TO), 0);
    thread_ = std::thread([this] { watch(); });
  }
  ~CheckpointRecorder() {
    if (thread_.joinable()) stop();
    close(fd_);
  }
  std::vector<fs::path> stop() {
    stopping_ = true;
    thread_.join();
    return versions_;
  }

 private:
  void watch() {
    alignas(inotify_event) char buffer[4096];
    for (;;) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 20) <= 0) {
        if (stopping_) return;  // nothing pending after the fit returned
        continue;
      }
      const ssize_t n = read(fd_, buffer, sizeof buffer);
      for (ssize_t i = 0; i < n;) {
        const auto* event = reinterpret_cast<const inotify_event*>(buffer + i);
        if (event->len > 0 && std::string(event->name) == "checkpoint.bin") {
          versions_.push_back(work_ / ("boundary" + std::to_string(versions_.size()) + ".bin"));
          fs::create_hard_link(work_ / "checkpoint.bin", versions_.back());
        }
        i += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
      }
    }
  }
  fs::path work_;
  int fd_;
  std::atomic<bool> stopping_{false};
  std::vector<fs::path> versions_;
  std::thread thread_;
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
  tbb::task_arena one(1);
  CheckpointRecorder recorder(work);
  one.execute([&] { runFit(work, c, false); });
  const std::vector<fs::path> boundaries = recorder.stop();
  const auto whole = fittedValues(work);
  expectBoundedFit(dir);
  // emission | albedo@32 | materials | albedo@64 | emission_texture |: the checkpoint after stage k
  // resumes at stage k + 1 (a run stopped after the recorder missed one would fail here).
  ASSERT_EQ(boundaries.size(), 5u);
  for (size_t k = 0; k < boundaries.size(); ++k) {
    const Checkpoint ck = Checkpoint::read(boundaries[k]);
    SCOPED_TRACE("resumed at stage " + std::to_string(ck.meta.value("stage", -1)));
    EXPECT_EQ(ck.meta.value("stage", -1), static_cast<int>(k) + 1);
    EXPECT_EQ(ck.meta.value("iteration", -1), 0);
    fs::remove_all(work / "result");
    fs::remove(work / "checkpoint.bin");  // a link to the last boundary: copying onto it would truncate that
    fs::copy_file(boundaries[k], work / "checkpoint.bin");
    one.execute([&] { runFit(work, c, true); });
    // Bound: bit-exact, every parameter of every group (emission textures included).
    expectSameFit(fittedValues(work), whole);
  }
}
