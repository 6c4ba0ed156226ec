// A camera's response: how an integer-encoded frame's code values (normalised to [0, 1]) map to
// linear values proportional to scene radiance. Float frames (EXR, HDR) are linear and never
// pass through it.
#pragma once
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "io/json.h"

namespace relume {

class Response {
 public:
  enum class Kind {
    Default,  // sRGB, unless the file says it is linear
    Srgb,
    Linear,
    Gamma,  // code^gamma
    Table,  // linear values at evenly spaced codes 0, 1/(n-1), ..., 1; interpolated linearly
  };

  Response() = default;
  static Response srgb() { return Response(Kind::Srgb); }
  static Response linear() { return Response(Kind::Linear); }
  static Response gamma(double g, std::string_view where);
  static Response table(std::vector<double> values, std::string_view where);
  // "srgb" | "linear" | "gamma:G" | "table:FILE" (FILE: whitespace-separated values, '#' comments;
  // relative to `dir`). Throws relume::Error naming `where`.
  static Response parse(std::string_view spec, const std::filesystem::path& dir, std::string_view where);
  // The transforms.json form: one of the strings above, {"gamma": G} or {"table": [values]}.
  static Response fromJson(const Json& j, const std::filesystem::path& dir, std::string_view where);

  Kind kind() const { return kind_; }
  std::string describe() const;
  std::string fingerprint() const;  // describe() and, for a table, every value
  // The linear value of a normalised code; `fileSaysLinear` decides the Default response.
  float toLinear(float code, bool fileSaysLinear) const;
  bool isDefault() const { return kind_ == Kind::Default; }

 private:
  explicit Response(Kind k) : kind_(k) {}
  Kind kind_ = Kind::Default;
  double gamma_ = 1.0;
  std::shared_ptr<const std::vector<float>> table_;
};

}  // namespace relume
