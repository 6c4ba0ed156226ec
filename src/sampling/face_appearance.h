// What the frames show of each face of a mesh (scene/segmentation.h's input): the median of its
// observations at four points of the face in up to `maxFrames` frames, with the spread and the
// share of clipped observations. An observation counts only where the pixels around it show the
// same surface (the camera rays 1.5 pixels away diagonally hit the face's connected component
// within `planeTolerance` of its plane): the pixel filter and the bilinear lookup blend a
// silhouette's pixels, so the ceiling around a lamp would otherwise look lit.
#pragma once
#include <vector>

#include "capture/frame_store.h"
#include "capture/transforms.h"
#include "scene/scene.h"
#include "scene/segmentation.h"

namespace relume {

struct FaceAppearanceOptions {
  size_t maxFrames = 32;       // of `use`, evenly spaced
  float radianceFloor = 1e-4f; // logs are taken of max(radiance, this)
  float minLogSpread = 0.1f;   // one observation's spread is taken as at least this (pixel noise, footprint)
  float planeTolerance = 0.02f; // of the camera's distance to the point
};

// One entry per face of scene.mesh(). The median is over the face's unclipped observations when it
// has any (a lamp seen unclipped in a bracket's dark frames shows its value there); its standard
// error is max(1.4826 x the median absolute deviation, minLogSpread) / sqrt(n). A face seen only
// clipped gets the largest of its floors.
std::vector<FaceAppearance> observeFaces(const Scene& scene, const std::vector<Frame>& frames,
                                         const FrameStore& store, const std::vector<size_t>& use,
                                         const FaceAppearanceOptions& options = {});

}  // namespace relume
