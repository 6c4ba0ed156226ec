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

// Runs `command` through the shell; its exit code and everything it printed.
inline RelumeRun runShell(const std::string& command) {
  const std::filesystem::path log =
      std::filesystem::temp_directory_path() / ("relume_run_" + std::to_string(getpid()) + ".log");
  const int status = std::system((command + " > " + log.string() + " 2>&1").c_str());
  RelumeRun run;
  if (WIFEXITED(status)) run.exitCode = WEXITSTATUS(status);
  std::stringstream out;
  out << std::ifstream(log).rdbuf();
  run.output = out.str();
  std::filesystem::remove(log);
  return run;
}

// `args` is passed through the shell: quote paths with spaces.
inline RelumeRun runRelume(const std::string& args) { return runShell(relumeBinary().string() + " " + args); }

// The mpirun (Open MPI) that starts RANKS processes: allowed as root (CI's containers), with more
// ranks than cores, without the single-copy transport containers forbid (it would only warn).
// Under AddressSanitizer without leak detection: Open MPI leaves about 116 KB at MPI_Finalize, in
// plugins it has unloaded by then, which no suppression can name (the same fits run as one
// process keep it).
inline std::string mpirunCommand(int ranks) {
#ifdef __SANITIZE_ADDRESS__
  const std::string sanitizers = "ASAN_OPTIONS=\"$ASAN_OPTIONS:detect_leaks=0\" ";
#else
  const std::string sanitizers;
#endif
  return sanitizers + "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun -np " +
         std::to_string(ranks) + " --oversubscribe --mca btl_vader_single_copy_mechanism none";
}

// `relume ARGS` as RANKS MPI ranks.
inline RelumeRun runRelumeRanks(int ranks, const std::string& args) {
  return runShell(mpirunCommand(ranks) + " " + relumeBinary().string() + " " + args);
}

}  // namespace relume
