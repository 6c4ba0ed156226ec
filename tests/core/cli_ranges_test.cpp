// Numeric command-line options are range-checked before anything runs (NaN included): runs the
// relume binary next to tests/ in the build tree.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace fs = std::filesystem;

extern char** environ;

namespace {
fs::path relumeBinary() { return fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "relume"; }
}  // namespace

TEST(Cli, NumericOptionsAreRangeChecked) {
  const fs::path relume = relumeBinary();
  ASSERT_TRUE(fs::exists(relume)) << relume;
  const fs::path log = fs::temp_directory_path() / "relume_cli_ranges.log";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"render --scene /dev/null --cameras /dev/null --out /tmp/relume_cli_x --spp -3",
       "--spp: -3 is not in [1, 1048576]"},
      {"synth --out /tmp/relume_cli_x --spp 0", "--spp: 0 is not in [1, 1048576]"},
      {"synth --out /tmp/relume_cli_x --width 4", "--width: 4 is not in [8, 65536]"},
      {"prepare /tmp --out /tmp/relume_cli_x --tile 0", "--tile: 0 is not in [1, 4096]"},
      {"prepare /tmp --out /tmp/relume_cli_x --gutter-res 0", "--gutter-res: 0 is not in [1, 65536]"},
      {"prepare /tmp --out /tmp/relume_cli_x --max-overexposed nan", "--max-overexposed: nan is not in [0, 1]"},
      {"prepare /tmp --out /tmp/relume_cli_x --downscale 0", "--downscale: 0 is not in [1, 64]"},
      {"gradcheck --emission-scale 1e38", "--emission-scale: 1e38 is not in"},
      {"gradcheck --eps nan", "--eps: nan is not in"},
      {"gradcheck --batches 1", "--batches: 1 is not in [2, 1048576]"},
      {"gradcheck --clip-high nan", "--clip-high: nan is not in"},
      {"profile --rays 0", "--rays: 0 is not in [1, 67108864]"},
      {"profile --scatter-res -1", "--scatter-res: -1 is not in [1, 32768]"},
  };
  for (const auto& [args, expected] : cases) {
    const int rc = std::system((relume.string() + " " + args + " > " + log.string() + " 2>&1").c_str());
    std::stringstream out;
    out << std::ifstream(log).rdbuf();
    EXPECT_NE(rc, 0) << args;
    EXPECT_NE(out.str().find(expected), std::string::npos) << args << ": " << out.str();
  }
}

// A command whose output is a pipe nobody reads any more (`relume synth ... 2>&1 | head -1` once
// head has exited) still finishes and writes its results: the first log line must not kill it with
// SIGPIPE.
TEST(Cli, ResultsOutliveClosedOutputStreams) {
  const fs::path relume = relumeBinary();
  const fs::path out = fs::temp_directory_path() / ("relume_cli_closed_stdout_" + std::to_string(getpid()));
  fs::remove_all(out);
  int fds[2];
  ASSERT_EQ(pipe2(fds, O_CLOEXEC), 0);
  close(fds[0]);  // the reader is gone before the command starts: its first write meets a closed pipe
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, fds[1], STDERR_FILENO);  // the log lines' stream
  // The child starts with SIGPIPE's default action whatever this test inherited, so only relume's
  // own handling can keep it alive.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t pipeSignal;
  sigemptyset(&pipeSignal);
  sigaddset(&pipeSignal, SIGPIPE);
  posix_spawnattr_setsigdefault(&attr, &pipeSignal);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGDEF);
  std::vector<std::string> args = {relume.string(), "--log",      "info",     "synth", "--scene",       "cornell",
                                   "--out",         out.string(), "--frames", "2",     "--test-frames", "1",
                                   "--width",       "16",         "--height", "16",    "--spp",         "1"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, relume.c_str(), &actions, &attr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  close(fds[1]);
  ASSERT_EQ(spawned, 0);
  int status = 0;
  ASSERT_EQ(waitpid(pid, &status, 0), pid);
  EXPECT_FALSE(WIFSIGNALED(status)) << "killed by signal " << WTERMSIG(status);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_TRUE(fs::exists(out / "transforms.json"));
  EXPECT_TRUE(fs::exists(out / "gt" / "scene.json"));
  fs::remove_all(out);
}

// Results go to stdout, logs to stderr: `relume profile ... > table.txt` holds the table alone.
TEST(Cli, LogsGoToStderrAndResultsToStdout) {
  const fs::path relume = relumeBinary();
  ASSERT_TRUE(fs::exists(relume)) << relume;
  const fs::path dir = fs::temp_directory_path() / ("relume_cli_streams_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const int rc = std::system(("'" + relume.string() + "'" +
                              " --log info profile --what render --synth cornell --width 16 --height 16 --spp 1"
                              " --max-depth 2 --repeats 1 > '" +
                              (dir / "out").string() + "' 2> '" + (dir / "err").string() + "'")
                                 .c_str());
  auto read = [&](const char* name) {
    std::stringstream s;
    s << std::ifstream(dir / name).rdbuf();
    return s.str();
  };
  const std::string out = read("out"), err = read("err");
  fs::remove_all(dir);
  EXPECT_EQ(rc, 0) << err;
  EXPECT_NE(out.find("efficiency"), std::string::npos) << out;  // the profile's table
  EXPECT_EQ(out.find("] info "), std::string::npos) << out;
  EXPECT_NE(err.find("] info peak RSS"), std::string::npos) << err;
  EXPECT_EQ(err.find("efficiency"), std::string::npos) << err;
}
