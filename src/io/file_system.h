// std::filesystem on the paths a user gives (inputs, output folders), each failure a one-line
// relume::Error naming the path and the reason (a symlink loop, a permission, a full disk) instead
// of a std::filesystem_error that would end the command as an internal error.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string_view>

namespace relume {

// False when nothing is at `path`; an entry that cannot be examined (a symlink loop, a folder
// without search permission) is an error, never taken for a missing one.
bool pathExists(const std::filesystem::path& path);
bool isDirectory(const std::filesystem::path& path);  // after symlinks; errors as pathExists
// Throws unless `path` (after symlinks) is a folder; `what` says what was expected.
void requireDirectory(const std::filesystem::path& path, std::string_view what);
uintmax_t fileSize(const std::filesystem::path& path);
// The absolute path with symlinks, "." and ".." resolved; the path must exist.
std::filesystem::path canonicalPath(const std::filesystem::path& path);
std::filesystem::path absolutePath(const std::filesystem::path& path);
// `path` relative to `base`, both resolved as far as they exist (std::filesystem::relative).
std::filesystem::path relativePath(const std::filesystem::path& path, const std::filesystem::path& base);
void createDirectories(const std::filesystem::path& path);
void removeAll(const std::filesystem::path& path);
void removeFile(const std::filesystem::path& path);  // nothing there is not an error
void renamePath(const std::filesystem::path& from, const std::filesystem::path& to);
void copyFileOver(const std::filesystem::path& from, const std::filesystem::path& to);  // replaces `to`

}  // namespace relume
