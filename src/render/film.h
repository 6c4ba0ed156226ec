// Rendering whole images from a camera: TBB over 16x16 tiles, one PCG32 per (pixel, sample, seed).
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "io/image.h"
#include "render/path_tracer.h"

namespace relume {

enum class Aov { Albedo, Normal, Depth, Object };
std::vector<Aov> parseAovs(const std::string& commaList);  // throws relume::Error on unknown names
const char* aovName(Aov aov);

struct RenderOptions {
  int spp = 16;
  uint64_t seed = 0;
  PathSettings path;
  std::vector<Aov> aovs;
};

// The primary ray of sample s of pixel (x, y): a position drawn from the camera's pixel filter, and the
// generator the rest of that path continues with. Shared by rendering and profiling, so the
// profiler replays exactly the rendered paths.
struct CameraSample {
  Pcg32 rng;
  std::optional<Vec3> dir;
};
CameraSample cameraSample(const Camera& camera, int x, int y, int s, uint64_t seed);

struct RenderStats {
  double seconds = 0;
  uint64_t paths = 0;
  uint64_t rays = 0;  // closest-hit + shadow rays actually traced
  // Paths whose radiance is not finite (overflowed on the way): left out of their pixel's mean and
  // counted, never silently. Within the radiance bound (kMaxEmission) none do.
  uint64_t nonFinitePaths = 0;
};

struct RenderResult {
  Image color;
  std::vector<Image> aovs;  // same order as RenderOptions::aovs
  RenderStats stats;
};

RenderResult renderImage(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                         const Camera& camera, const RenderOptions& options);

}  // namespace relume
