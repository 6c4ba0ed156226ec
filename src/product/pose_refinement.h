// Pose refinement (issue 39): a frame's 6-DoF pose corrected so that the current reconstruction,
// rendered from it, lines up with what the frame shows. Direct image alignment of the render's
// surface points onto the frame (Gauss-Newton on a robust log-luminance error over an image
// pyramid, with a per-frame brightness offset), run between fit stages (docs/design/poses.md).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"
#include "io/json.h"
#include "render/path_tracer.h"

namespace relume {

class FrameStore;

struct PoseAlignSettings {
  int width = 320;               // the frames are aligned at most this wide (integer box downscale)
  int levels = 3;                // pyramid levels, each half the last: a correction of ~2^levels pixels is found
  int iterations = 15;           // Gauss-Newton iterations per level at most
  int minPixels = 300;           // a frame with fewer usable pixels at the finest level is not aligned
  double maxTranslation = 0.1;   // metres: a larger correction is taken for a failure
  double maxRotationDeg = 5.0;   // degrees: likewise
  double minConditioning = 1e-5;  // smallest over largest eigenvalue of the pose block (depth-scaled)
  // The given pose's accuracy, a Gaussian prior on the correction (per axis): the estimate stays
  // near the given pose along directions the frame does not fix.
  double priorTranslation = 0.02;  // metres
  double priorRotationDeg = 0.5;
};

// A frame as the aligner reads it: linear luminance (gain and exposure divided out) at a size
// whose camera is `camera`; NaN where the pixel is masked or clipped (it bounds, it does not tell).
struct AlignImage {
  int width = 0, height = 0;
  std::vector<float> luminance;  // row-major, row 0 at the top
};

// Frame `frame` of `store` box-downscaled to at most `maxWidth` pixels wide, luminance divided by
// `gain`; `camera` (the frame's) comes back with the matching intrinsics and a unit box filter.
AlignImage alignImageFromStore(const FrameStore& store, size_t frame, float gain, int maxWidth, Camera& camera);

enum class AlignStatus { Aligned, Unchanged, Failed };
const char* alignStatusName(AlignStatus s);

struct FrameAlignment {
  AlignStatus status = AlignStatus::Unchanged;
  std::string why;         // for Unchanged and Failed
  Camera camera;           // the refined pose (the given one unless Aligned)
  double costBefore = 0;   // robust cost per pixel at the finest level, brightness offset fitted
  double costAfter = 0;
  int pixels = 0;          // usable at the finest level
  double conditioning = 0;
};

// What a frame is aligned with: an image of what its pixels should show, on `targetGrid(camera)`.
// That grid is half a pixel off the frame's, so that at the given pose the frame is read half-way
// between its pixels. Reading an image between its pixels averages their noise, the more so the
// nearer the middle: read at its pixel centres, the cost falls as the pose moves off them and
// pulls every pose a fraction of a pixel (measured: 1-3 mm and 0.03-0.08 deg off a right pose);
// half-way, that variance is flat in the offset and pulls nothing.
Camera targetGrid(const Camera& camera);
// The reconstruction rendered on `grid` with `spp` paths per pixel.
AlignImage renderedTarget(const Scene& scene, const Appearance& model, const LightSampler& lights, const Camera& grid,
                          int spp, uint64_t seed, const PathSettings& path);
// Aligns `frame` (seen by `camera`) with `target` (on targetGrid(camera), both at `camera`'s size);
// the target's surface points are the first hits of its pixel centres. Never returns a pose whose
// cost at the finest level is above the given pose's.
FrameAlignment alignFrame(const Scene& scene, const Camera& camera, const AlignImage& frame, const AlignImage& target,
                          const PoseAlignSettings& s);

// The correction from `from` to `to`: translation in metres, rotation in degrees.
double poseTranslation(const Camera& from, const Camera& to);
double poseRotationDeg(const Camera& from, const Camera& to);

}  // namespace relume
