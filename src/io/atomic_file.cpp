#include "io/atomic_file.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <fstream>
#include <regex>

#include "core/error.h"

namespace relume {

void writeAtomically(const std::filesystem::path& path,
                     const std::function<void(const std::filesystem::path&)>& write) {
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  // Keep the extension last: image writers choose the format from it.
  const std::filesystem::path tmp =
      path.parent_path() / fmt::format(".{}.tmp{}{}", path.stem().string(), getpid(), path.extension().string());
  try {
    write(tmp);
    std::filesystem::rename(tmp, path);
  } catch (...) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw;
  }
}

size_t removeStaleTemporaries(const std::filesystem::path& dir) {
  // The name writeAtomically gives: ".<stem>.tmp<pid><extension>".
  static const std::regex kTemporary(R"(\..+\.tmp([0-9]{1,9})(\.[^.]*)?)");
  size_t removed = 0;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    std::smatch m;
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file(ec) || !std::regex_match(name, m, kTemporary)) continue;
    const pid_t pid = static_cast<pid_t>(std::stol(m[1].str()));
    const bool writerAlive = pid == getpid() || kill(pid, 0) == 0 || errno == EPERM;
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
