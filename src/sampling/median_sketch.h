// Streaming per-texel median in O(1) memory per texel (prepare's initial albedo): a coarse log
// histogram locates the median's bin, a second pass over the same observations refines it with
// sub-bins inside that bin.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/math.h"

namespace relume {

class MedianSketch {
 public:
  static constexpr int kBins = 16, kSub = 32;
  static constexpr float kLogMin = -4.0f, kLogMax = 4.0f;
  // Every array is allocated here, once, at its largest (the fine histogram's size also holds the
  // coarse one): a sketch reused by restart() never reallocates, so the heap does not grow in
  // steps as it would with arrays freed and allocated again at other sizes.
  explicit MedianSketch(size_t texels)
      : hist_(texels * 3 * kSub, 0),
        count_(texels, 0),
        target_(texels * 3),
        below_(texels * 3),
        binIndex_(texels * 3) {}
  // The bytes a texel holds: its histogram (sub-bins), bin, rank and count.
  static constexpr double kBytesPerTexel = 3.0 * kSub * sizeof(uint16_t) + 3.0 * (2 * sizeof(uint32_t) + 1) + 4;
  // Empty again, for another set of texels (no more than the constructor's).
  void restart() {
    std::fill(hist_.begin(), hist_.end(), uint16_t{0});
    std::fill(count_.begin(), count_.end(), 0u);
  }
  static int binOfLog(float l) { return std::clamp(static_cast<int>((l - kLogMin) / width()), 0, kBins - 1); }
  void addCoarse(size_t t, const Color& c) {
    for (int ch = 0; ch < 3; ++ch) {
      uint16_t& b = hist_[(t * 3 + ch) * kBins + binOfLog(std::log10(std::max(c[ch], 1e-12f)))];
      b = static_cast<uint16_t>(std::min(65535, b + 1));
    }
    count_[t] = std::min<uint32_t>(count_[t] + 1, 65535);
  }
  // After the coarse pass: pick each channel's median bin, then empty the histogram for the fine
  // pass.
  void startFine() {
    for (size_t t = 0; t < count_.size(); ++t)
      for (int ch = 0; ch < 3; ++ch) {
        const size_t k = t * 3 + ch;
        const uint32_t half = (count_[t] + 1) / 2;
        uint32_t cum = 0;
        int b = 0;
        for (; b < kBins; ++b) {
          if (cum + hist_[k * kBins + b] >= half) break;
          cum += hist_[k * kBins + b];
        }
        binIndex_[k] = static_cast<uint8_t>(std::min(b, kBins - 1));
        below_[k] = cum;
        target_[k] = half;
      }
    std::fill(hist_.begin(), hist_.end(), uint16_t{0});
  }
  void addFine(size_t t, const Color& c) {
    for (int ch = 0; ch < 3; ++ch) {
      const size_t k = t * 3 + ch;
      const float lo = kLogMin + binIndex_[k] * width();
      const float l = std::log10(std::max(c[ch], 1e-12f));
      if (binIndex_[k] != binOfLog(l)) continue;
      const int s = std::clamp(static_cast<int>((l - lo) / (width() / kSub)), 0, kSub - 1);
      uint16_t& b = hist_[k * kSub + s];
      b = static_cast<uint16_t>(std::min(65535, b + 1));
    }
  }
  uint32_t count(size_t t) const { return count_[t]; }
  Color median(size_t t) const {
    Color out;
    for (int ch = 0; ch < 3; ++ch) {
      const size_t k = t * 3 + ch;
      uint32_t cum = below_[k];
      const float lo = kLogMin + binIndex_[k] * width(), sub = width() / kSub;
      float l = lo + width();
      for (int s = 0; s < kSub; ++s) {
        const uint16_t n = hist_[k * kSub + s];
        if (n > 0 && cum + n >= target_[k]) {
          l = lo + sub * (s + (static_cast<float>(target_[k] - cum) - 0.5f) / n);  // interpolate inside the sub-bin
          break;
        }
        cum += n;
      }
      out[ch] = l <= kLogMin + 1e-3f ? 0.0f : std::pow(10.0f, l);
    }
    return out;
  }

 private:
  static constexpr float width() { return (kLogMax - kLogMin) / kBins; }
  std::vector<uint16_t> hist_;  // per texel and channel: kBins counts in the coarse pass, kSub in the fine one
  std::vector<uint32_t> count_;
  std::vector<uint32_t> target_, below_;
  std::vector<uint8_t> binIndex_;
};

}  // namespace relume
