// Outputs are never half-written: write to a temporary sibling, then rename over the target.
#pragma once
#include <filesystem>
#include <functional>
#include <string_view>

namespace relume {

// Calls write(tempPath) and renames tempPath to path; removes the temporary on failure.
void writeAtomically(const std::filesystem::path& path,
                     const std::function<void(const std::filesystem::path&)>& write);
void writeTextAtomically(const std::filesystem::path& path, std::string_view text);

}  // namespace relume
