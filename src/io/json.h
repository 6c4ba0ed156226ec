// JSON loading with file-named errors.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>

#include "core/error.h"

namespace relume {

using Json = nlohmann::json;
Json readJson(const std::filesystem::path& path);
void writeJson(const std::filesystem::path& path, const Json& json);  // atomic, pretty-printed

// Typed field access that reports "file: key: expected ..." instead of a bare nlohmann exception.
double jsonNumber(const Json& j, const char* key, const std::filesystem::path& file);
double jsonNumberOr(const Json& j, const char* key, double fallback, const std::filesystem::path& file);

// Runs a reader, turning nlohmann's exceptions (a field of the wrong type, say) into a one-line
// relume::Error that names the file.
template <typename Parse>
auto withJsonErrors(const std::filesystem::path& file, Parse&& parse) -> decltype(parse()) {
  try {
    return parse();
  } catch (const Json::exception& e) {
    fail("{}: {}", file.string(), e.what());
  }
}

}  // namespace relume
