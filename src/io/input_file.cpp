#include "io/input_file.h"

#include <fstream>
#include <iterator>

#include "core/error.h"

namespace relume {

void requireRegularFile(const std::filesystem::path& path, std::string_view what) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  // Unknown status: the path exists but cannot be examined (a symlink loop, no permission).
  if (!std::filesystem::status_known(st))
    fail("{}: cannot access: {} (expected {})", path.string(), ec.message(), what);
  if (!std::filesystem::exists(st)) fail("{}: not found (expected {})", path.string(), what);
  if (std::filesystem::is_directory(st)) fail("{}: is a directory, expected {}", path.string(), what);
  if (!std::filesystem::is_regular_file(st))
    fail("{}: is not a regular file (a device, FIFO or socket), expected {}", path.string(), what);
}

std::string readRegularFile(const std::filesystem::path& path, std::string_view what) {
  requireRegularFile(path, what);
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open {}", path.string(), what);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace relume
