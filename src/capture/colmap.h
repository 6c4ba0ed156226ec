// COLMAP sparse models as relume frames: cameras.{txt,bin} + images.{txt,bin}. points3D is neither
// needed nor read. COLMAP's conventions are relume's (OpenCV axes, pixel centres at +0.5); its
// poses are world-to-camera and are inverted on reading.
#pragma once
#include <filesystem>
#include <vector>

#include "capture/transforms.h"

namespace relume {

enum class ColmapFormat { Text, Binary };

// True if `model` holds cameras.txt + images.txt or cameras.bin + images.bin.
bool hasColmapModel(const std::filesystem::path& model);

// Reads the model in `model` (binary if cameras.bin and images.bin exist, as COLMAP itself does,
// else text), each image NAME relative to `images`. Models SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL,
// RADIAL, OPENCV (and FULL_OPENCV without its rational terms k4-k6). Frames are sorted by NAME;
// their exposure is 1, not recorded. Bad input throws a one-line relume::Error naming the file,
// the camera or image and the field.
Capture readColmap(const std::filesystem::path& model, const std::filesystem::path& images);

// Writes cameras, images and an empty points3D (text or binary; doubles round-trip exactly) into
// `model`: one COLMAP camera per distinct intrinsics (PINHOLE, OPENCV, or FULL_OPENCV when k3 is
// set), image ids 1..n in the frames' order, NAMEs relative to `images`. COLMAP holds no exposure,
// clip thresholds or pixel filter: those are dropped, with a warning.
void writeColmap(const std::filesystem::path& model, const std::filesystem::path& images,
                 const std::vector<Frame>& frames, ColmapFormat format);

}  // namespace relume
