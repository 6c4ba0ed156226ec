// JSON loading with file-named errors.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>
#include <nlohmann/json.hpp>

#include "core/error.h"

namespace relume {

using Json = nlohmann::json;
Json readJson(const std::filesystem::path& path);
void writeJson(const std::filesystem::path& path, const Json& json);  // atomic, pretty-printed

// Typed field access that reports "file: key: expected ..." instead of a bare nlohmann exception.
double jsonNumber(const Json& j, const char* key, const std::filesystem::path& file);
double jsonNumberOr(const Json& j, const char* key, double fallback, const std::filesystem::path& file);
// An integer in [lo, hi], read as 64-bit (get<int>() would wrap 4294967296 onto 0, and a float
// such as 1e85 cast to an integer is undefined behaviour): "where: 'field' ..." otherwise.
int64_t jsonInteger(const Json& v, int64_t lo, int64_t hi, const std::string& where, const std::string& field);
template <typename T>
std::vector<T> jsonIntegers(const Json& v, int64_t lo, int64_t hi, const std::string& where, const std::string& field) {
  if (!v.is_array()) fail("{}: '{}' must be an array of integers", where, field);
  std::vector<T> out;
  for (const Json& e : v) out.push_back(static_cast<T>(jsonInteger(e, lo, hi, where, field)));
  return out;
}

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
