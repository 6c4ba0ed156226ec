// Measured cost of the renderer and (later) of an optimisation iteration, by phase.
#pragma once
#include "pipeline/synth.h"
#include "render/path_tracer.h"

namespace relume {

struct RenderProfile {
  int width = 0, height = 0, spp = 0, maxDepth = 0, threads = 0;
  double renderSeconds = 0, traceOnlySeconds = 0;
  uint64_t paths = 0, closestRays = 0, shadowRays = 0;
  double efficiency() const { return traceOnlySeconds / renderSeconds; }
};

// Renders one view, then replays exactly the same rays through Embree alone.
RenderProfile profileRender(const SceneDescription& scene, const Camera& camera, int spp, int maxDepth);

}  // namespace relume
