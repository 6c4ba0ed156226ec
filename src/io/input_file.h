// Every reader checks its input here first: a missing path, a directory, or a device/FIFO (which
// would block, or stream forever like /dev/zero) gets a one-line error naming the path.
#pragma once
#include <filesystem>
#include <string>
#include <string_view>

namespace relume {

// Throws relume::Error unless `path` (after symlinks) is a regular file; `what` says what was expected.
void requireRegularFile(const std::filesystem::path& path, std::string_view what);
// requireRegularFile, then the whole file.
std::string readRegularFile(const std::filesystem::path& path, std::string_view what);

}  // namespace relume
