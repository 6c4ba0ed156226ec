// `relume degrade`: a clean capture with linear (float) frames, such as a Cycles render of a scene
// whose truth you hold, rewritten as a hand-held camera would have delivered it: the flaws of
// `synth --imperfect` (scenes/imperfections.h) applied to its training frames, cameras and mesh,
// their truth in gt/imperfections.json. The held-out frames are copied unchanged: they stay the
// judge. A clean `synth` capture degraded with a spec and seed is byte for byte the capture
// `synth --imperfect` writes with them.
#pragma once
#include <cstdint>
#include <filesystem>

#include "scenes/imperfections.h"

namespace relume {

struct DegradeOptions {
  std::filesystem::path capture;  // transforms.json or a COLMAP model; float frames
  std::filesystem::path out;      // a new or empty folder
  ImperfectionSpec spec;
  uint64_t seed = 1;
};

struct DegradeSummary {
  int framesWritten = 0, framesLeftOut = 0, heldOutCopied = 0;
  size_t maskedPixels = 0;  // masked (non-finite) source pixel channels, written as 0
};

// Writes mesh.ply, objects.json (kept segmentation), images/, transforms.json, the source's
// transforms_test.json and the held-out images it names, gt/ (the source's, plus imperfections.json
// and, with mesh noise, mesh_clean.ply). Throws relume::Error naming the file when a training frame
// is integer-encoded (already clipped and quantised), when the capture has flaws already
// (gt/imperfections.json), or when `out` is the capture or holds files.
DegradeSummary degradeCapture(const DegradeOptions& options);

}  // namespace relume
