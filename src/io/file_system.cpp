#include "io/file_system.h"

#include "core/error.h"

namespace relume {
namespace fs = std::filesystem;

namespace {
// "path: what failed: reason", one line.
void failIf(const std::error_code& ec, const fs::path& path, std::string_view what) {
  if (ec) fail("{}: {}: {}", path.string(), what, ec.message());
}
}  // namespace

bool pathExists(const fs::path& path) {
  std::error_code ec;
  const bool exists = fs::exists(path, ec);  // clears ec when the path is simply missing
  failIf(ec, path, "cannot access");
  return exists;
}

bool isDirectory(const fs::path& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (st.type() == fs::file_type::not_found) return false;
  failIf(ec, path, "cannot access");
  return fs::is_directory(st);
}

void requireDirectory(const fs::path& path, std::string_view what) {
  if (!pathExists(path)) fail("{}: not found (expected {})", path.string(), what);
  if (!isDirectory(path)) fail("{}: is not a folder, expected {}", path.string(), what);
}

uintmax_t fileSize(const fs::path& path) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(path, ec);
  failIf(ec, path, "cannot read the size");
  return size;
}

fs::path canonicalPath(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::canonical(path, ec);
  failIf(ec, path, "cannot resolve");
  return p;
}

fs::path absolutePath(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::absolute(path, ec);
  failIf(ec, path, "cannot make absolute");
  return p;
}

fs::path relativePath(const fs::path& path, const fs::path& base) {
  std::error_code ec;
  fs::path p = fs::relative(path, base, ec);
  failIf(ec, path, fmt::format("cannot express relative to {}", base.string()));
  return p;
}

void createDirectories(const fs::path& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  failIf(ec, path, "cannot create the folder");
}

void removeAll(const fs::path& path) {
  std::error_code ec;
  fs::remove_all(path, ec);
  failIf(ec, path, "cannot remove");
}

void removeFile(const fs::path& path) {
  std::error_code ec;
  fs::remove(path, ec);
  failIf(ec, path, "cannot remove");
}

void renamePath(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::rename(from, to, ec);
  failIf(ec, to, fmt::format("cannot rename {} to it", from.string()));
}

void copyFileOver(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
  failIf(ec, to, fmt::format("cannot copy {} to it", from.string()));
}

}  // namespace relume
