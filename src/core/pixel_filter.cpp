#include "core/pixel_filter.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/math.h"

namespace relume {
namespace {
constexpr int kBins = 1024;
constexpr float kMaxWidth = 16.0f;
}  // namespace

PixelFilter::PixelFilter(PixelFilterType type, float width) : type_(type), width_(width) {
  if (!(width > 0.0f && width <= kMaxWidth)) fail("pixel filter width {}: must be in (0, {}] pixels", width, kMaxWidth);
  if (type == PixelFilterType::Box) return;
  auto cdf = std::make_shared<std::vector<float>>(kBins + 1, 0.0f);
  const double r = radius(), step = 2.0 * r / kBins;
  double sum = 0;
  for (int i = 0; i < kBins; ++i) {
    const double a = -r + i * step;
    sum += step / 6.0 * (weight(float(a)) + 4.0 * weight(float(a + 0.5 * step)) + weight(float(a + step)));
    (*cdf)[i + 1] = static_cast<float>(sum);
  }
  cdf_ = std::move(cdf);
}

PixelFilter PixelFilter::parse(const std::string& type, std::optional<double> width) {
  const float w = static_cast<float>(width.value_or(type == "box" ? 1.0 : 1.5));
  if (type == "box") return {PixelFilterType::Box, w};
  if (type == "gaussian") return {PixelFilterType::Gaussian, w};
  if (type == "blackman-harris") return {PixelFilterType::BlackmanHarris, w};
  fail("pixel filter '{}': must be box, gaussian or blackman-harris", type);
}

PixelFilter PixelFilter::parseSpec(const std::string& spec) {
  const size_t colon = spec.find(':');
  if (colon == std::string::npos) return parse(spec);
  const std::string width = spec.substr(colon + 1);
  size_t used = 0;
  double w = 0;
  try {
    w = std::stod(width, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != width.size()) fail("pixel filter '{}': the width after ':' must be a number", spec);
  return parse(spec.substr(0, colon), w);
}

const char* PixelFilter::name() const {
  switch (type_) {
    case PixelFilterType::Box:
      return "box";
    case PixelFilterType::Gaussian:
      return "gaussian";
    case PixelFilterType::BlackmanHarris:
      return "blackman-harris";
  }
  return "";
}

float PixelFilter::radius() const {
  switch (type_) {
    case PixelFilterType::Box:
      return 0.5f * width_;
    case PixelFilterType::Gaussian:
      return 1.5f * width_;
    case PixelFilterType::BlackmanHarris:
      return width_;
  }
  return 0.5f * width_;
}

float PixelFilter::weight(float x) const {
  if (std::abs(x) > radius()) return 0.0f;
  switch (type_) {
    case PixelFilterType::Box:
      return 1.0f;
    case PixelFilterType::Gaussian:
      return std::exp(-8.0f * x * x / (width_ * width_));
    case PixelFilterType::BlackmanHarris: {
      const float v = 2.0f * kPi * (x / (2.0f * width_) + 0.5f);
      return 0.35875f - 0.48829f * std::cos(v) + 0.14128f * std::cos(2.0f * v) - 0.01168f * std::cos(3.0f * v);
    }
  }
  return 0.0f;
}

float PixelFilter::sample(float u) const {
  if (type_ == PixelFilterType::Box) return u * width_ + 0.5f * (1.0f - width_);
  const std::vector<float>& cdf = *cdf_;
  const float target = u * cdf.back();
  const int bin = std::clamp(int(std::upper_bound(cdf.begin(), cdf.end(), target) - cdf.begin()) - 1, 0, kBins - 1);
  const float mass = cdf[bin + 1] - cdf[bin];
  const float t = mass > 0.0f ? std::clamp((target - cdf[bin]) / mass, 0.0f, 1.0f) : 0.5f;
  return 0.5f + radius() * (-1.0f + 2.0f * (bin + t) / kBins);
}

}  // namespace relume
