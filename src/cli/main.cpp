// The relume executable: parses subcommands and calls the pipeline; holds no algorithm.
#include <CLI/CLI.hpp>
#include <sched.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <csignal>
#include <filesystem>
#include <new>
#include <system_error>
#include <thread>

#include "cli/commands.h"
#include "core/error.h"
#include "core/ranks.h"
#include "core/system.h"

namespace {
// Exit codes: 1 for what the user or the machine caused (bad input, a full disk, a closed pipe, too
// little memory); 70 (EX_SOFTWARE, sysexits.h) for an exception relume's code never meant to throw.
// A failed CHECK aborts (core/check.h); command-line parse errors keep CLI11's codes.
constexpr int kInputError = 1, kInternalError = 70;

// Only the fit and prepare split their work between MPI ranks; any other command run as several
// would repeat the same work and write the same files from every rank.
void checkRanksFor(const std::string& command) {
  const int launched = relume::MpiSession::launchedRanks();
  if (launched > 1 && !relume::MpiSession::available())
    relume::fail("relume was built without MPI: run it as one process, or rebuild with Open MPI installed "
                 "(libopenmpi-dev) to run `mpirun -np {} relume {}`", launched, command == "prepare" ? "prepare" : "fit");
  if (relume::Ranks::world().distributed() && command != "fit" && command != "prepare")
    relume::fail("`relume {}` runs as one process; only `relume fit` and `relume prepare` split their work between "
                 "MPI ranks (this job has {})", command, relume::Ranks::world().size());
}
}  // namespace

int main(int argc, char** argv) {
  // Output piped into a reader that stops early (`relume eval ... | head -2`) must not kill a
  // command before it has written its results. Ignored, SIGPIPE becomes a failed write: log lines
  // are dropped, and a print throws (the command then ends with exit 1), so commands write their
  // results before printing them.
  std::signal(SIGPIPE, SIG_IGN);
  CLI::App app{"relume: relightable materials and lights from scanned indoor scenes"};
  app.require_subcommand(1);
  int threads = 0;
  std::string logLevel = "info";
  app.add_option("--threads", threads, "worker threads (0 = all cores)");
  app.add_option("--log", logLevel, "log level: debug, info, warn, error");
  const relume::CommandTable commands = relume::registerCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  // Logs go to stderr, results (tables, reports) to stdout: `relume profile ... > table.txt` holds
  // the table alone, and a script reading a command's output never parses log lines.
  spdlog::set_default_logger(spdlog::stderr_color_mt("relume"));
  spdlog::set_level(spdlog::level::from_str(logLevel));
  spdlog::set_pattern("[%T] %^%l%$ %v");
  // Under mpirun (core/ranks.h): the root logs; the other ranks say only what goes wrong on them.
  const relume::MpiSession mpi;
  relume::Ranks& ranks = relume::Ranks::world();
  if (ranks.distributed()) {
    spdlog::set_pattern(fmt::format("[%T] rank {} %^%l%$ %v", ranks.rank()));
    if (!ranks.root()) spdlog::set_level(spdlog::level::err);
    // The host's cores shared between its ranks, within the cores the launcher bound this rank to
    // (Open MPI binds a rank to one core up to 2 ranks: `--bind-to none` leaves them all), unless
    // --threads says otherwise.
    if (threads == 0) {
      const int host = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
      cpu_set_t bound;
      const int usable = sched_getaffinity(0, sizeof bound, &bound) == 0 ? CPU_COUNT(&bound) : host;
      threads = std::max(1, std::min(usable, host / ranks.ranksOnThisHost()));
    }
  }
  auto pool = relume::initThreads(threads);
  // An error ends the whole job: the other ranks would otherwise wait for this one.
  auto failed = [&](int code) {
    if (ranks.distributed()) ranks.abort(code);
    return code;
  };
  try {
    const CLI::App* command = app.get_subcommands().front();
    checkRanksFor(command->get_name());
    const int rc = commands.at(command)();
    spdlog::info("peak RSS {:.0f} MiB", relume::peakRssMiB());
    return rc;
  } catch (const relume::Error& e) {
    spdlog::error("{}", e.what());
    return failed(kInputError);
  } catch (const std::filesystem::filesystem_error& e) {
    // Every filesystem call on a user's path reports its own relume::Error (io/file_system.h): one
    // that gets here is a call that was missed.
    spdlog::error("internal error: {}", e.what());
    return failed(kInternalError);
  } catch (const std::system_error& e) {
    // The environment, not relume: a print into a closed pipe (SIGPIPE is ignored, above).
    spdlog::error("{}", e.what());
    return failed(kInputError);
  } catch (const std::bad_alloc&) {
    spdlog::error("out of memory (peak RSS {:.0f} MiB)", relume::peakRssMiB());
    return failed(kInputError);
  } catch (const std::exception& e) {
    spdlog::error("internal error: {}", e.what());
    return failed(kInternalError);
  }
}
