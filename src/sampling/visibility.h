// Which frames see which surface points. `observe` is the one connection test every stage uses
// (prepare's visibility index and median, the texture-space sampler): inside the image, not
// edge-on, unoccluded. The visibility index lists, per tile of texture space, the frames that
// can see some point of it (CSR), so samplers only try plausible frames.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <vector>

#include "capture/transforms.h"
#include "scene/scene.h"
#include "scene/texel_map.h"

namespace relume {

// Where camera `cam` would see surface point p with normal n were nothing in between: the pixel,
// if p is inside the image (half a pixel in) and not seen edge-on (from either side of n: the BSDF
// is two-sided). NaN-safe: a non-finite point or normal is never in view.
std::optional<Vec2> inView(const Camera& cam, const Vec3& p, const Vec3& n);

// inView, and nothing lies between the camera and p (one occlusion ray).
std::optional<Vec2> observe(const Scene& scene, const Camera& cam, const Vec3& p, const Vec3& n);

struct VisibilityIndex {
  int resolution = 0, tileTexels = 0, tilesPerSide = 0;
  std::vector<uint32_t> offsets;  // tiles + 1
  std::vector<uint32_t> frames;
  size_t tileOf(size_t texel, int texelResolution) const;  // texel of any resolution that is a multiple of ours
  size_t frameCount(size_t tile) const { return offsets[tile + 1] - offsets[tile]; }
  const uint32_t* framesOf(size_t tile) const { return frames.data() + offsets[tile]; }
  void write(const std::filesystem::path& path) const;
  // Throws relume::Error on a bad file, or one naming a frame index >= frameCount.
  static VisibilityIndex read(const std::filesystem::path& path, size_t frameCount = SIZE_MAX);
  size_t bytes() const { return (offsets.size() + frames.size()) * sizeof(uint32_t); }
};

// Frames (of `use`) that see each tile of `map`: frustum, not edge-on, one occlusion ray per test point.
VisibilityIndex buildVisibilityIndex(const Scene& scene, const TexelMap& map, const std::vector<Frame>& frames,
                                     const std::vector<size_t>& use, int tileTexels, int samplesPerTile);

}  // namespace relume
