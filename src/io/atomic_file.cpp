#include "io/atomic_file.h"

#include <unistd.h>

#include <fstream>

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

void writeTextAtomically(const std::filesystem::path& path, std::string_view text) {
  writeAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    if (!out) fail("{}: cannot write", path.string());
  });
}

}  // namespace relume
