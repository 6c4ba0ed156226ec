// The pixel (reconstruction) filter a frame was formed with: a pixel's value is the image-plane
// radiance weighted by f(x - cx) f(y - cy) around its centre (separable) and normalised. Rays drawn
// from f have the pixel as their expectation, so renders and pixel-footprint training rays use the
// capture's own filter. Box (width 1) is relume's own renderer's; Gaussian and Blackman-Harris are
// defined as Blender Cycles defines its "Filter Width" w (intern/cycles/scene/film.cpp): Gaussian
// exp(-8 x^2 / w^2) (sigma w/4) over |x| <= 1.5 w, Blackman-Harris a four-term window of total
// width 2w over |x| <= w. Cycles' default is Blackman-Harris, w = 1.5 px.
#pragma once
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace relume {

enum class PixelFilterType { Box, Gaussian, BlackmanHarris };

class PixelFilter {
 public:
  PixelFilter() = default;  // box, width 1
  PixelFilter(PixelFilterType type, float width);
  // "box" | "gaussian" | "blackman-harris", width in pixels in (0, 16] (without one: 1 for a box,
  // Cycles' default 1.5 otherwise); a one-line error otherwise.
  static PixelFilter parse(const std::string& type, std::optional<double> width = std::nullopt);
  static PixelFilter parseSpec(const std::string& spec);  // "TYPE[:WIDTH]", the command line's form

  PixelFilterType type() const { return type_; }
  const char* name() const;
  float width() const { return width_; }
  float radius() const;         // f is 0 beyond it
  float weight(float x) const;  // f(x), unnormalised, x from the pixel centre
  // A position from the pixel's top-left corner (in pixels) distributed as f around the centre
  // 0.5, for u uniform in [0, 1). The unit box maps u to itself, bit for bit.
  float sample(float u) const;
  bool isUnitBox() const { return type_ == PixelFilterType::Box && width_ == 1.0f; }
  bool operator==(const PixelFilter& o) const { return type_ == o.type_ && width_ == o.width_; }

 private:
  PixelFilterType type_ = PixelFilterType::Box;
  float width_ = 1.0f;
  // Gaussian and Blackman-Harris: the CDF of f over [-radius, radius] at kBins + 1 equally spaced
  // points (f integrated exactly per bin by Simpson's rule, linear within a bin when sampling).
  std::shared_ptr<const std::vector<float>> cdf_;
};

}  // namespace relume
