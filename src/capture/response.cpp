#include "capture/response.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/error.h"
#include "io/image.h"
#include "io/input_file.h"

namespace relume {
namespace {

constexpr double kMinGamma = 0.1, kMaxGamma = 10.0;
// Enough for a 16-bit calibration; a longer table is not a response.
constexpr size_t kMaxTableEntries = 65536;
// Linear values a table may hold: it is relative radiance, and the frame store keeps half floats.
constexpr double kMaxTableValue = 65504.0;

std::vector<double> readTableFile(const std::filesystem::path& file) {
  const std::string text = readRegularFile(file, "a response table (whitespace-separated values)");
  std::vector<double> values;
  std::istringstream lines(text);
  std::string line;
  for (size_t lineNo = 1; std::getline(lines, line); ++lineNo) {
    if (const size_t hash = line.find('#'); hash != std::string::npos) line.resize(hash);
    std::istringstream words(line);
    std::string word;
    while (words >> word) {
      char* end = nullptr;
      const double v = std::strtod(word.c_str(), &end);
      if (end != word.c_str() + word.size()) fail("{}: line {}: '{}' is not a number", file.string(), lineNo, word);
      values.push_back(v);
      if (values.size() > kMaxTableEntries)
        fail("{}: more than {} values (a response table has one per code)", file.string(), kMaxTableEntries);
    }
  }
  return values;
}

}  // namespace

Response Response::gamma(double g, std::string_view where) {
  if (!(g >= kMinGamma && g <= kMaxGamma))
    fail("{}: response gamma {} must be in [{}, {}]", where, g, kMinGamma, kMaxGamma);
  Response r(Kind::Gamma);
  r.gamma_ = g;
  return r;
}

Response Response::table(std::vector<double> values, std::string_view where) {
  if (values.size() < 2 || values.size() > kMaxTableEntries)
    fail("{}: a response table needs 2 to {} values (the linear value at each code), not {}", where, kMaxTableEntries,
         values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    if (!(std::isfinite(values[i]) && values[i] >= 0 && values[i] <= kMaxTableValue))
      fail("{}: response table entry {} is {}, must be in [0, {}]", where, i, values[i], kMaxTableValue);
    // Strictly increasing: a flat or falling stretch maps different radiance to one code.
    if (i > 0 && !(values[i] > values[i - 1]))
      fail("{}: response table is not monotonic: entry {} ({}) is not above entry {} ({})", where, i, values[i], i - 1,
           values[i - 1]);
  }
  Response r(Kind::Table);
  auto t = std::make_shared<std::vector<float>>();
  for (double v : values) t->push_back(static_cast<float>(v));
  r.table_ = std::move(t);
  return r;
}

Response Response::parse(std::string_view spec, const std::filesystem::path& dir, std::string_view where) {
  if (spec == "srgb") return srgb();
  if (spec == "linear") return linear();
  const auto colon = spec.find(':');
  const std::string_view head = spec.substr(0, colon), arg = colon == spec.npos ? "" : spec.substr(colon + 1);
  if (head == "gamma" && !arg.empty()) {
    const std::string s(arg);
    char* end = nullptr;
    const double g = std::strtod(s.c_str(), &end);
    if (end != s.c_str() + s.size()) fail("{}: response 'gamma:{}': not a number", where, s);
    return gamma(g, where);
  }
  if (head == "table" && !arg.empty()) {
    const std::filesystem::path file = dir / std::string(arg);
    return table(readTableFile(file), file.string());
  }
  fail("{}: response '{}' is not one of srgb, linear, gamma:G, table:FILE", where, spec);
}

Response Response::fromJson(const Json& j, const std::filesystem::path& dir, std::string_view where) {
  if (j.is_string()) return parse(j.get<std::string>(), dir, where);
  if (j.is_object() && j.size() == 1 && j.contains("gamma") && j["gamma"].is_number())
    return gamma(j["gamma"].get<double>(), where);
  if (j.is_object() && j.size() == 1 && j.contains("table") && j["table"].is_array()) {
    std::vector<double> values;
    for (const Json& v : j["table"]) {
      if (!v.is_number()) fail("{}: 'response.table' must hold numbers", where);
      values.push_back(v.get<double>());
    }
    return table(std::move(values), where);
  }
  fail(
      "{}: 'response' must be \"srgb\", \"linear\", \"gamma:G\", \"table:FILE\", {{\"gamma\": G}} or {{\"table\": "
      "[...]}}",
      where);
}

std::string Response::describe() const {
  switch (kind_) {
    case Kind::Default:
      return "srgb (linear where the file says so)";
    case Kind::Srgb:
      return "srgb";
    case Kind::Linear:
      return "linear";
    case Kind::Gamma:
      return fmt::format("gamma {}", gamma_);
    case Kind::Table:
      return fmt::format("table of {} values", table_->size());
  }
  return "";
}

std::string Response::fingerprint() const {
  std::string s = describe();
  if (table_)
    for (float v : *table_) s += fmt::format(" {}", v);
  return s;
}

float Response::toLinear(float code, bool fileSaysLinear) const {
  switch (kind_) {
    case Kind::Default:
      return fileSaysLinear ? code : srgbToLinear(code);
    case Kind::Srgb:
      return srgbToLinear(code);
    case Kind::Linear:
      return code;
    case Kind::Gamma:
      return static_cast<float>(std::pow(std::max(0.0f, code), gamma_));
    case Kind::Table: {
      const std::vector<float>& t = *table_;
      const float x = std::clamp(code, 0.0f, 1.0f) * static_cast<float>(t.size() - 1);
      const size_t i = std::min(static_cast<size_t>(x), t.size() - 2);
      const float f = x - static_cast<float>(i);
      return t[i] + f * (t[i + 1] - t[i]);
    }
  }
  return code;
}

}  // namespace relume
