// Outputs are never half-written: write to a temporary sibling, then rename over the target.
#pragma once
#include <filesystem>
#include <functional>
#include <string_view>

namespace relume {

// Calls write(tempPath) and renames tempPath to path; removes the temporary on failure.
void writeAtomically(const std::filesystem::path& path, const std::function<void(const std::filesystem::path&)>& write);
void writeTextAtomically(const std::filesystem::path& path, std::string_view text);
// A killed run leaves its temporary behind (named after the target and the writer's pid). Removes
// those in `dir` whose writer is no longer running; returns how many. Never throws: a read-only
// folder simply keeps them.
size_t removeStaleTemporaries(const std::filesystem::path& dir);

}  // namespace relume
