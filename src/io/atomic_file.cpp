#include "io/atomic_file.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <fstream>
#include <string>

#include "core/error.h"
#include "core/kill_point.h"
#include "io/file_system.h"

namespace relume {

void writeAtomically(const std::filesystem::path& path,
                     const std::function<void(const std::filesystem::path&)>& write) {
  if (path.has_parent_path()) createDirectories(path.parent_path());
  // Keep the extension last: image writers choose the format from it.
  const std::filesystem::path tmp =
      path.parent_path() / fmt::format(".{}.tmp{}{}", path.stem().string(), getpid(), path.extension().string());
  try {
    write(tmp);
    killPoint("atomic-write");
    renamePath(tmp, path);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
}

namespace {
// The writer's pid if `name` is one writeAtomically gives, ".<stem>.tmp<pid><extension>"; else 0.
pid_t temporaryWriter(const std::string& name) {
  const size_t tmp = name.rfind(".tmp");
  if (name.empty() || name[0] != '.' || tmp == std::string::npos || tmp < 2) return 0;
  const char* end = name.data() + name.size();
  pid_t pid = 0;
  const auto [digitsEnd, ec] = std::from_chars(name.data() + tmp + 4, end, pid);
  const std::string_view extension(digitsEnd, static_cast<size_t>(end - digitsEnd));
  if (ec != std::errc() || pid <= 0) return 0;
  if (!extension.empty() && (extension[0] != '.' || extension.find('.', 1) != std::string_view::npos)) return 0;
  return pid;
}

// Whether `pid` is a process that can still write: it exists and is not a zombie. A writer killed
// under `timeout -s KILL` stays a zombie until its new parent reaps it, which a container's pid 1
// may never do; kill(pid, 0) alone still counts such a writer alive.
bool processRunning(pid_t pid) {
  if (kill(pid, 0) != 0 && errno != EPERM) return false;
  std::ifstream stat(fmt::format("/proc/{}/stat", pid));
  std::string line;
  if (!std::getline(stat, line)) return true;  // no /proc: trust kill()
  // "pid (comm) state ...": comm may hold spaces and parentheses, so read after the last ')'.
  const size_t close = line.rfind(')');
  if (close == std::string::npos || close + 2 >= line.size()) return true;
  const char state = line[close + 2];
  return state != 'Z' && state != 'X';
}
}  // namespace

size_t removeStaleTemporaries(const std::filesystem::path& dir) {
  size_t removed = 0;
  std::error_code ec;
  // increment(ec): the range-for's operator++ would throw on a folder that fails mid-listing.
  for (std::filesystem::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::filesystem::directory_entry& entry = *it;
    const pid_t pid = temporaryWriter(entry.path().filename().string());
    if (!pid || !entry.is_regular_file(ec)) continue;
    const bool writerAlive = pid == getpid() || processRunning(pid);
    if (!writerAlive && std::filesystem::remove(entry.path(), ec)) ++removed;
  }
  return removed;
}

void writeTextAtomically(const std::filesystem::path& path, std::string_view text) {
  writeAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    if (!out) fail("{}: cannot write", path.string());
  });
}

}  // namespace relume
