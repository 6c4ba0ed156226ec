// Runs the relume binary of the build tree (next to the test binaries' folder) and returns its exit
// code and everything it printed (stdout and stderr): for tests of what a user sees.
#pragma once
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace relume {

struct RelumeRun {
  int exitCode = -1;  // -1: killed by a signal
  std::string output;
};

inline std::filesystem::path relumeBinary() {
  return std::filesystem::read_symlink("/proc/self/exe").parent_path().parent_path() / "relume";
}

// `args` is passed through the shell: quote paths with spaces.
inline RelumeRun runRelume(const std::string& args) {
  const std::filesystem::path log =
      std::filesystem::temp_directory_path() / ("relume_run_" + std::to_string(getpid()) + ".log");
  const int status = std::system((relumeBinary().string() + " " + args + " > " + log.string() + " 2>&1").c_str());
  RelumeRun run;
  if (WIFEXITED(status)) run.exitCode = WEXITSTATUS(status);
  std::stringstream out;
  out << std::ifstream(log).rdbuf();
  run.output = out.str();
  std::filesystem::remove(log);
  return run;
}

}  // namespace relume
