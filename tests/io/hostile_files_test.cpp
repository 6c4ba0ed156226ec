// Non-regular inputs (a device, a FIFO, a directory) give a one-line error naming the path instead
// of hanging; temporaries of killed runs are recognised and removed.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/image.h"
#include "io/json.h"
#include "io/mesh_data.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path freshDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// Every reader on `path`: each must throw relume::Error whose message names the path and contains `why`.
void expectEveryReaderRejects(const fs::path& path, const std::string& why) {
  const std::vector<std::function<void()>> readers = {[&] { readImage(path); }, [&] { readJson(path); },
                                                      [&] { readPly(path); }, [&] { readObj(path); }};
  for (const auto& read : readers) {
    try {
      read();
      ADD_FAILURE() << path << " was read";
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(path.string()), std::string::npos) << msg;
      EXPECT_NE(msg.find(why), std::string::npos) << msg;
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
}

}  // namespace

TEST(HostileFiles, SymlinkToDevZeroIsRejectedNotStreamed) {
  const fs::path dir = freshDir("relume_hostile_zero");
  fs::create_symlink("/dev/zero", dir / "frame.exr");
  expectEveryReaderRejects(dir / "frame.exr", "not a regular file");
}

TEST(HostileFiles, FifoIsRejectedWithoutBlocking) {
  const fs::path dir = freshDir("relume_hostile_fifo");
  ASSERT_EQ(mkfifo((dir / "frame.png").c_str(), 0600), 0);
  expectEveryReaderRejects(dir / "frame.png", "not a regular file");
}

TEST(HostileFiles, DirectoryWhereAFileIsExpectedIsNamed) {
  const fs::path dir = freshDir("relume_hostile_dir");
  fs::create_directories(dir / "mesh.ply");
  expectEveryReaderRejects(dir / "mesh.ply", "is a directory");
}

// A number beyond double's range is nlohmann's out_of_range, not a parse error: still a one-line
// error naming the file (found by fuzzing frame_gains.json).
TEST(HostileFiles, JsonNumberBeyondDoubleIsAnErrorNamingTheFile) {
  const fs::path file = freshDir("relume_json_overflow") / "gains.json";
  std::ofstream(file) << R"({"frames": [{"frame": 1, "gain": [1e2238, 1, 1]}]})";
  try {
    (void)readJson(file);
    FAIL() << "read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(file.string() + ": malformed JSON"), std::string::npos) << e.what();
  }
}

TEST(AtomicFile, TemporariesOfDeadWritersAreRemovedOthersKept) {
  const fs::path dir = freshDir("relume_stale_tmp");
  // pid_max is at most 2^22 on Linux, so pid 999999999 never runs.
  const std::vector<std::string> stale = {".frames.tmp999999999.bin", ".albedo_init.tmp999999999.exr",
                                          ".prepare.tmp999999999.json"};
  const std::vector<std::string> kept = {fmt::format(".checkpoint.tmp{}.bin", getpid()),  // our own, being written
                                         "frames.bin", "notes.tmp999999999", ".tmp999999999"};
  for (const auto& name : stale) std::ofstream(dir / name) << "partial";
  for (const auto& name : kept) std::ofstream(dir / name) << "keep";
  EXPECT_EQ(removeStaleTemporaries(dir), stale.size());
  for (const auto& name : stale) EXPECT_FALSE(fs::exists(dir / name)) << name;
  for (const auto& name : kept) EXPECT_TRUE(fs::exists(dir / name)) << name;
  EXPECT_EQ(removeStaleTemporaries(dir / "missing"), 0u);  // never throws
}

// A writer killed under `timeout -s KILL` is a zombie nobody reaps; its temporary is stale.
TEST(AtomicFile, AZombieWritersTemporaryIsStale) {
  const fs::path dir = freshDir("relume_zombie_tmp");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) _exit(0);
  // Not reaped until the end: until then the child is a zombie.
  siginfo_t info{};
  ASSERT_EQ(waitid(P_PID, static_cast<id_t>(child), &info, WEXITED | WNOWAIT), 0);
  const fs::path temporary = dir / fmt::format(".frames.tmp{}.bin", child);
  std::ofstream(temporary) << "partial";
  EXPECT_EQ(removeStaleTemporaries(dir), 1u);
  EXPECT_FALSE(fs::exists(temporary));
  waitpid(child, nullptr, 0);
}
