#include "io/json.h"

#include <fstream>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/input_file.h"

namespace relume {

Json readJson(const std::filesystem::path& path) {
  const std::string text = readRegularFile(path, "a JSON file");
  try {
    return Json::parse(text);
  } catch (const Json::parse_error& e) {
    fail("{}: malformed JSON at byte {}", path.string(), e.byte);
  } catch (const Json::exception& e) {  // a number beyond double's range: out_of_range, not parse_error
    fail("{}: malformed JSON: {}", path.string(), e.what());
  }
}

void writeJson(const std::filesystem::path& path, const Json& json) { writeTextAtomically(path, json.dump(2) + "\n"); }

double jsonNumber(const Json& j, const char* key, const std::filesystem::path& file) {
  if (!j.is_object() || !j.contains(key)) fail("{}: missing field '{}'", file.string(), key);
  const Json& v = j.at(key);
  if (!v.is_number()) fail("{}: field '{}' must be a number", file.string(), key);
  const double d = v.get<double>();
  if (!std::isfinite(d)) fail("{}: field '{}' is not finite", file.string(), key);
  return d;
}

double jsonNumberOr(const Json& j, const char* key, double fallback, const std::filesystem::path& file) {
  return j.is_object() && j.contains(key) ? jsonNumber(j, key, file) : fallback;
}

int64_t jsonInteger(const Json& v, int64_t lo, int64_t hi, const std::string& where, const std::string& field) {
  if (!v.is_number_integer()) fail("{}: '{}' must be an integer", where, field);
  // Unsigned values above INT64_MAX are out of any int64 range; below it they read exactly as int64.
  const bool fits = !v.is_number_unsigned() || v.get<uint64_t>() <= static_cast<uint64_t>(INT64_MAX);
  const int64_t i = fits ? v.get<int64_t>() : 0;
  if (!fits || i < lo || i > hi) fail("{}: '{}' is {}, must be in [{}, {}]", where, field, v.dump(), lo, hi);
  return i;
}

}  // namespace relume
