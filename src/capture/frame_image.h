// A frame's pixels as scene radiance: the image read, linearised by the frame's response (integer
// encodings), divided by its exposure, NaN/Inf masked; with the thresholds beyond which a value
// only bounds the radiance (a saturated channel: at least that much; a black one: at most).
#pragma once
#include "capture/transforms.h"
#include "io/image.h"

namespace relume {

struct FrameImage {
  Image image;          // linear, exposure-corrected; masked pixels are kMaskedPixel
  ImageReadStats read;  // encoding and non-finite pixels of the file
  // In the image's values. An integer encoding clips at its largest code and at 0: the thresholds
  // lie half a code inside them (and, at the top, at least one half-float step below, so that
  // the frame store's rounding cannot move a saturated value under it). The frame's own
  // clip_high/clip_low can only tighten them. Float images: the frame's values (none by default).
  float clipLow = 0.0f;
  float clipHigh = std::numeric_limits<float>::infinity();
};

// Throws relume::Error naming the file when it cannot be read or its size differs from the camera's.
// `encodingClips` false (an ablation) treats an integer encoding's extreme codes as exact values.
FrameImage loadFrame(const Frame& frame, bool encodingClips = true);
inline Image loadFrameImage(const Frame& frame) { return loadFrame(frame).image; }

}  // namespace relume
