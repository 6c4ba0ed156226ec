// All frames of a capture converted once to one half-float file, memory-mapped for reading: any
// pixel is available with no decoding, and resident memory does not grow with the frame count.
// Layout: header, an index entry per frame, then RGB half pixels (row 0 at the top; masked
// pixels are stored as -1).
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <vector>

#include "capture/transforms.h"

namespace relume {

struct FrameStats {
  uint32_t width = 0, height = 0;  // as stored (after downscaling)
  uint32_t downscale = 1;
  float overexposed = 0;   // fraction of pixels with a channel at or above clipHigh
  float underexposed = 0;  // fraction of pixels with every channel at or below clipLow
  float masked = 0;        // fraction of NaN/Inf pixels
  // The frame's clip thresholds (FrameImage) in the stored values, and its file's encoding.
  float clipLow = 0;
  float clipHigh = std::numeric_limits<float>::infinity();
  uint32_t bits = 0;  // 8 or 16: integer-encoded; 0: float
};

// Converts every frame (images read through loadFrame: response and exposure applied, NaN
// masked), optionally box-filtered by an integer `downscale` (a block with a masked pixel is
// masked, and so is one whose mean is a mix of saturated and exact values: it bounds nothing).
// Exposure statistics are taken at full resolution. `encodingClips`: as loadFrame's. `progress` is
// called once per frame this process decodes. Atomic: the file appears complete or not at all.
// Over MPI ranks (core/ranks.h), a collective: frame i is decoded by rank i mod N and written into
// the root's temporary (the work folder is on a filesystem every rank shares), and every rank
// returns every frame's statistics.
std::vector<FrameStats> writeFrameStore(const std::filesystem::path& path, const std::vector<Frame>& frames,
                                        int downscale = 1, bool encodingClips = true,
                                        const std::function<void()>& progress = {});

class FrameStore {
 public:
  explicit FrameStore(const std::filesystem::path& path);  // throws relume::Error on a bad file
  ~FrameStore();
  FrameStore(const FrameStore&) = delete;
  FrameStore& operator=(const FrameStore&) = delete;

  size_t frameCount() const { return index_.size(); }
  size_t mappedBytes() const { return size_; }
  const FrameStats& stats(size_t frame) const { return index_[frame].stats; }
  Color pixel(size_t frame, int x, int y) const;  // negative = masked
  // Bilinear at continuous pixel coordinates of the ORIGINAL image (pixel centres at +0.5; the
  // downscale is applied here); nullopt if outside the image, if any of the four pixels is masked,
  // or if a channel mixes saturated and unsaturated pixels (the blend would be neither a value
  // nor a bound).
  std::optional<Color> bilinear(size_t frame, const Vec2& pixel) const;
  // The stored pixel containing `pixel` (ORIGINAL image coordinates) and its extent there: the
  // square of `size` x `size` original pixels from `corner` (size = the downscale). nullopt if
  // outside the image or masked.
  struct StoredPixel {
    Color value;
    Vec2 corner;
    float size = 1;
  };
  std::optional<StoredPixel> pixelAt(size_t frame, const Vec2& pixel) const;
  // Starts loading the stored pixels bilinear or pixelAt at `pixel` would read (a hint: no pixel
  // is read, nothing faults), so a caller can overlap that miss with other work.
  void prefetch(size_t frame, const Vec2& pixel) const;

 private:
  struct Entry {
    uint64_t offset;
    FrameStats stats;
  };
  std::vector<Entry> index_;
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
};

}  // namespace relume
