// JSON loading with file-named errors.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>

namespace relume {

using Json = nlohmann::json;
Json readJson(const std::filesystem::path& path);
void writeJson(const std::filesystem::path& path, const Json& json);  // atomic, pretty-printed

// Typed field access that reports "file: key: expected ..." instead of a bare nlohmann exception.
double jsonNumber(const Json& j, const char* key, const std::filesystem::path& file);
double jsonNumberOr(const Json& j, const char* key, double fallback, const std::filesystem::path& file);

}  // namespace relume
