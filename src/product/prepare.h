// `relume prepare CAPTURE --out WORK`: everything the optimiser needs to sample the unknowns in
// texture space, built once per capture. Phases (each skipped when its inputs are unchanged):
//   frames      frames.bin (half-float, mmap-able) + frame filtering (exposure, motion)
//   segmentation  segments.bin + objects.json: objects computed from the mesh and the frames
//               (scene/segmentation.h), when the mesh has none (or `--segmentation computed`)
//   atlas       atlas_mesh.ply (uv atlas; texel maps are rebuilt from it in < 1 s per stage)
//   visibility  visibility.bin: per 32x32-texel tile of the init resolution, the frames that see it
//   init        albedo_init.exr (per-texel streaming median of observed radiance),
//               coverage.exr / coverage.png (observations per texel)
// and prepare.json with counts, timings, peak RSS and every dropped frame with its reason.
#pragma once
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "capture/transforms.h"
#include "core/enum_names.h"
#include "sampling/face_appearance.h"
#include "scene/atlas.h"
#include "scene/scene.h"
#include "scene/segmentation.h"
#include "scene/texel_map.h"
#include "sampling/visibility.h"

namespace relume {

enum class InitStatistic { Median, Mean };

// Where the objects come from: `given` the mesh's own ids (one object when it has none);
// `computed` a segmentation from the mesh and the frames, ignoring any ids; `auto` computed when
// the mesh has a single object, else given.
enum class SegmentationMode { Auto, Given, Computed };
template <>
struct EnumNames<SegmentationMode> {
  static constexpr std::array<std::pair<SegmentationMode, std::string_view>, 3> values{
      {{SegmentationMode::Auto, "auto"}, {SegmentationMode::Given, "given"}, {SegmentationMode::Computed, "computed"}}};
};

struct PrepareOptions {
  std::vector<int> resolutions = {1024, 2048, 4096};  // the first is the init resolution
  float maxOverexposed = 0.3f;                        // drop frames with more than this fraction of saturated pixels
  float maxUnderexposed = 0.6f;                       // ... or of pixels at or below clip_low
  float maxSpeed = 1.0f;                              // metres between neighbouring frames (motion blur proxy; photo
                                                      // sets are sparse, so the defaults only catch real jumps)
  float maxAngularSpeed = 45.0f;                      // degrees between neighbouring frames
  int tileTexels = 32;                                // visibility tile size at the init resolution
  int samplesPerTile = 6;                             // surface points tested per tile and frame
  int downscale = 1;                                  // box-filter frames by this factor in the cache (disk: 6 B/pixel)
  std::string response;       // of 8/16-bit frames (capture/response.h); empty: the capture's own, else sRGB
  bool encodingClips = true;  // 8/16-bit extreme codes bound the loss one-sidedly (false: the ablation)
  InitStatistic init = InitStatistic::Median;
  SegmentationMode segmentation = SegmentationMode::Auto;
  SegmentationOptions segmentationOptions;
  FaceAppearanceOptions faceAppearance;
  bool force = false;  // redo every phase
  // Stay within this many bytes (0: no budget): the init phase planned to fit, or the run refused
  // before it, or before any work when even the leanest plan cannot fit (product/prepare_memory.h).
  double memoryBudgetBytes = 0;
  AtlasOptions atlas;
};

struct PrepareSummary {
  size_t frames = 0, keptFrames = 0, triangles = 0;
  double fractionUnobserved = 0;  // valid texels at the init resolution never observed
  double seconds = 0;
};

// The capture folder a work folder was prepared from (prepare.json's "capture").
std::filesystem::path capturePreparedIn(const std::filesystem::path& work);

PrepareSummary prepareCapture(const std::filesystem::path& capture, const std::filesystem::path& work,
                              const PrepareOptions& options);

// The capture's frames as prepare read them: with the --response it was given (prepare.json
// keeps it), so that whatever re-reads the frames (the report) decodes them alike.
void applyPreparedResponse(const Json& prepare, std::vector<Frame>& frames);

}  // namespace relume
