#include "capture/frame_image.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "core/error.h"

namespace relume {
namespace {

// The frame store keeps half floats: 2^-10 is one step of their 10-bit mantissa.
constexpr float kHalfStep = 1.0f / 1024.0f;

void setClipThresholds(FrameImage& f, const Frame& frame, bool encodingClips) {
  const float inv = 1.0f / frame.exposure;
  if (f.read.bits == 0 || !encodingClips) {
    f.clipLow = frame.clipLow, f.clipHigh = frame.clipHigh;
    return;
  }
  const float maxCode = static_cast<float>((1 << f.read.bits) - 1);
  const auto linear = [&](float code) { return frame.response.toLinear(code / maxCode, f.read.fileSaysLinear); };
  const float top = std::min(linear(maxCode - 0.5f), linear(maxCode) * (1.0f - kHalfStep));
  f.clipHigh = std::min(top * inv, frame.clipHigh);
  f.clipLow = std::max(linear(0.5f) * inv, frame.clipLow);
}

}  // namespace

FrameImage loadFrame(const Frame& frame, bool encodingClips) {
  FrameImage f;
  Image& img = f.image;
  img = readImageCodes(frame.image, &f.read);
  if (img.width != frame.camera.width || img.height != frame.camera.height)
    fail("{}: image is {}x{} but {} says {}x{}", frame.image.string(), img.width, img.height,
         frame.cameraSource.empty() ? "its camera" : frame.cameraSource, frame.camera.width, frame.camera.height);
  if (f.read.bits == 0 && !frame.response.isDefault())
    spdlog::warn("{}: a float image is linear; the capture's response ({}) is not applied", frame.image.string(),
                 frame.response.describe());
  const float inv = 1.0f / frame.exposure;
  for (float& v : img.rgb) v = (f.read.bits ? frame.response.toLinear(v, f.read.fileSaysLinear) : v) * inv;
  // A huge finite pixel may overflow once divided by a small exposure: masked like NaN/Inf on disk.
  for (size_t i = 0; i < img.rgb.size() / 3; ++i)
    if (!isFinite(Color(img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2])))
      f.read.nonFiniteIndex.push_back(i), ++f.read.nonFinitePixels;
  if (f.read.nonFinitePixels)
    spdlog::warn("{}: {} NaN/Inf pixels masked", frame.image.string(), f.read.nonFinitePixels);
  for (size_t i : f.read.nonFiniteIndex) img.rgb[3 * i] = img.rgb[3 * i + 1] = img.rgb[3 * i + 2] = kMaskedPixel;
  setClipThresholds(f, frame, encodingClips);
  return f;
}

}  // namespace relume
