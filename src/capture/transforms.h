// Posed frames in the nerfstudio transforms.json convention.
#pragma once
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "capture/response.h"
#include "core/camera.h"

namespace relume {

struct Frame {
  Camera camera;
  std::filesystem::path image;    // absolute
  std::string cameraSource;       // the file and entry that gave `camera` ("F: frame 3"), named by errors
  float exposure = 1.0f;          // pixels are divided by it to get scene radiance
  bool exposureRecorded = false;  // the capture gave `exposure` (else 1 is assumed, not known)
  // Clip thresholds in the linear (exposure-corrected) domain: values at or beyond them are
  // saturated (high) or buried in noise (low) and only constrain the loss one-sidedly.
  float clipLow = 0.0f;
  float clipHigh = std::numeric_limits<float>::infinity();
  Response response;  // of integer-encoded images (the capture's `response`)
  // The frame's albedo pass (`albedo_path`: a synthetic capture's diffuse colour, linear, the
  // frame's size), which `relume eval` compares the fit's albedo with; empty when there is none.
  std::filesystem::path albedo;
};

struct Capture {
  std::filesystem::path file;                // transforms.json, or COLMAP's images.txt|bin
  std::vector<std::filesystem::path> files;  // every file the cameras were read from (fingerprints)
  std::vector<Frame> frames;
  // The poses are exact (a rendered capture: `exact_poses` in transforms.json), not a
  // reconstruction's estimate; refine_poses auto leaves them as they are.
  bool exactPoses = false;
};

// Throws relume::Error naming the file, the frame index and the field.
Capture readTransforms(const std::filesystem::path& path);
// Writes frames with paths relative to the json's folder (atomic); `exactPoses` as Capture's.
void writeTransforms(const std::filesystem::path& path, const std::vector<Frame>& frames, bool exactPoses = false);
// Radiance is never negative, so a negative value marks a pixel that must not be used (NaN/Inf on disk).
inline constexpr float kMaskedPixel = -1.0f;

}  // namespace relume
