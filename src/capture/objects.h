// Optional objects.json naming the segments of a capture's mesh.
#pragma once
#include <filesystem>
#include <map>
#include <string>

namespace relume {

// Accepts {"objects": [{"id": 0, "name": "floor"}, ...]} or {"0": "floor", ...}.
// Throws relume::Error naming the file and the entry on malformed input.
std::map<int, std::string> readObjectNames(const std::filesystem::path& path);

}  // namespace relume
