// Image I/O through OpenImageIO. In memory every image is linear RGB float32.
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "core/math.h"

namespace relume {

struct Image {
  int width = 0, height = 0;
  std::vector<float> rgb;  // row-major, row 0 at the top, 3 floats per pixel
  Image() = default;
  Image(int w, int h) : width(w), height(h), rgb(static_cast<size_t>(w) * h * 3, 0.0f) {}
  Color at(int x, int y) const {
    const float* p = &rgb[3 * (static_cast<size_t>(y) * width + x)];
    return {p[0], p[1], p[2]};
  }
  void set(int x, int y, const Color& c) {
    float* p = &rgb[3 * (static_cast<size_t>(y) * width + x)];
    p[0] = c[0], p[1] = c[1], p[2] = c[2];
  }
};

// Pixels with a NaN or infinite channel.
size_t countNonFinitePixels(const Image& image);

struct ImageReadStats {
  size_t nonFinitePixels = 0;          // NaN/Inf pixels, set to 0 and counted
  std::vector<size_t> nonFiniteIndex;  // their pixel indices, so callers can mask them
  int bits = 0;                        // 8 or 16 for an integer encoding, 0 for float
  bool fileSaysLinear = false;         // an integer file tagged as holding linear values
};

// Larger images are rejected before anything is allocated (8192 x 8192 is the largest square).
inline constexpr int64_t kMaxImagePixels = int64_t{1} << 26;
// EXR/HDR are read as linear; 8/16-bit integer formats are sRGB-decoded. Greyscale is expanded,
// alpha dropped. NaN/Inf pixels become 0 and are counted in `stats`.
Image readImage(const std::filesystem::path& path, ImageReadStats* stats = nullptr);
// As readImage, but an integer encoding's values are its codes normalised to [0, 1], undecoded
// (the caller applies a camera response).
Image readImageCodes(const std::filesystem::path& path, ImageReadStats* stats = nullptr);
// Float EXR (never half: small gradients and bright emitters would not survive). Atomic.
void writeExr(const std::filesystem::path& path, const Image& image);
// Tone-mapped preview: exposure scale, clamp, sRGB encode, 8-bit PNG. Atomic.
void writePng(const std::filesystem::path& path, const Image& image, float exposure = 1.0f);
// sRGB-encoded PNG of [0,1]-clamped linear values with 8 or 16 bits per channel: as a file
// (atomic) or as the bytes of one (glTF embeds them).
void writeSrgbPng(const std::filesystem::path& path, const Image& image, int bits);
std::vector<uint8_t> encodeSrgbPng(const Image& image, int bits);

float srgbToLinear(float v);
float linearToSrgb(float v);

}  // namespace relume
