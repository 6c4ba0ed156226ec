// RGB float texture over the uv atlas, possibly only a window of it (emission textures are
// allocated only over their emitter's charts). Bilinear lookup at x = u*W - 0.5 (pbrt), clamped
// to the window; the gradient scatter uses exactly the same four texels and weights.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "core/math.h"

namespace relume {

struct TexelFootprint {
  std::array<uint32_t, 4> index{};  // texel indices inside the window's storage
  std::array<float, 4> weight{};
};

struct Texture {
  int fullWidth = 0, fullHeight = 0;          // resolution of the whole atlas this texture lives in
  int x0 = 0, y0 = 0, width = 0, height = 0;  // the stored window
  std::vector<float> rgb;

  Texture() = default;
  Texture(int w, int h, const Color& fill = Color::Zero()) : Texture(w, h, 0, 0, w, h, fill) {}
  Texture(int fullW, int fullH, int wx0, int wy0, int w, int h, const Color& fill = Color::Zero())
      : fullWidth(fullW),
        fullHeight(fullH),
        x0(wx0),
        y0(wy0),
        width(w),
        height(h),
        rgb(static_cast<size_t>(w) * h * 3) {
    for (size_t i = 0; i < rgb.size(); i += 3) rgb[i] = fill[0], rgb[i + 1] = fill[1], rgb[i + 2] = fill[2];
  }
  bool empty() const { return rgb.empty(); }
  size_t texelCount() const { return static_cast<size_t>(width) * height; }

  TexelFootprint footprint(const Vec2& uv) const {
    const float x = uv.x() * static_cast<float>(fullWidth) - 0.5f - static_cast<float>(x0);
    const float y = uv.y() * static_cast<float>(fullHeight) - 0.5f - static_cast<float>(y0);
    const float fx = std::floor(x), fy = std::floor(y);
    const float dx = x - fx, dy = y - fy;
    auto clampX = [&](int i) { return static_cast<uint32_t>(std::clamp(i, 0, width - 1)); };
    auto clampY = [&](int j) { return static_cast<uint32_t>(std::clamp(j, 0, height - 1)); };
    const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
    const uint32_t xa = clampX(ix), xb = clampX(ix + 1), ya = clampY(iy), yb = clampY(iy + 1);
    TexelFootprint f;
    f.index = {ya * width + xa, ya * width + xb, yb * width + xa, yb * width + xb};
    f.weight = {(1 - dx) * (1 - dy), dx * (1 - dy), (1 - dx) * dy, dx * dy};
    return f;
  }
  Color texel(uint32_t i) const { return {rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]}; }
  Color lookup(const TexelFootprint& f) const {
    Color c = Color::Zero();
    for (int k = 0; k < 4; ++k) c += f.weight[k] * texel(f.index[k]);
    return c;
  }
  Color lookup(const Vec2& uv) const { return lookup(footprint(uv)); }
  // Starts loading the texels lookup(uv) reads: a wavefront of paths issues it a bounce phase
  // ahead of the lookup, so the random access into a large atlas overlaps other paths' work.
  // always_inline: GCC 12 deems a function made only of prefetches free of effects and deletes
  // every call to it before inlining (checked: no prefetcht0 left in the render kernel).
  [[gnu::always_inline]] void prefetch(const Vec2& uv) const {
    const TexelFootprint f = footprint(uv);
    for (int k = 0; k < 4; k += 2) {  // each row: its first texel's first float, its second's last
      __builtin_prefetch(&rgb[3 * f.index[k]]);
      __builtin_prefetch(&rgb[3 * f.index[k + 1] + 2]);
    }
  }
};

}  // namespace relume
