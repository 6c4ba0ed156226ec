// Training batches. The texture-space sampler (the paper's, 3.3) draws texels uniformly from the
// valid texels of the current resolution, maps them to surface points through the texel map and
// connects each to up to K frames that see it (candidates from the visibility index; inside the
// frustum, not edge-on (either side), and the camera ray's first hit must be that surface point).
// The image-space sampler (random frames, random pixels) is the ablation's baseline. Both are
// deterministic: slot j of iteration i is seeded from (seed, i, j), whatever the thread count.
#pragma once
#include <array>
#include <span>
#include <string>
#include <vector>

#include "capture/frame_store.h"
#include "core/enum_names.h"
#include "core/rng.h"
#include "io/json.h"
#include "sampling/batch.h"
#include "sampling/visibility.h"

namespace relume {

// The frames a sampler may use: cameras, the cached pixels (with their clip thresholds), and which
// frames prepare kept.
struct TrainingFrames {
  const std::vector<Frame>* frames = nullptr;
  const FrameStore* store = nullptr;
  std::vector<uint32_t> usable;
};

struct SamplerStats {
  size_t slots = 0;              // texels (or pixels) drawn
  size_t candidates = 0;         // frame connections tried
  size_t notSeen = 0;            // outside the image, edge-on, occluded
  size_t firstHitElsewhere = 0;  // the camera ray first hits another surface (grazing, self-occlusion)
  size_t masked = 0;             // reference pixel masked (NaN/Inf in the input)
  size_t disagreeing = 0;        // left out: the reference disagrees with its texel's other frames
  size_t rays = 0;               // training rays produced
  void add(const SamplerStats& o);
  Json toJson() const;
};

// A batch and, per ray, the surface it was aimed at (texture space: the texel slot it came from).
struct Batch {
  std::vector<BatchRay> rays;
  std::vector<uint32_t> slot;   // which drawn texel (or pixel) produced the ray
  std::vector<int> object;      // the object of the targeted surface point
  std::vector<uint32_t> frame;  // the frame whose pixel is the ray's reference
  std::vector<uint32_t> texel;  // per slot: the texel drawn (texture-space sampler; empty for image space)
  SamplerStats stats;
  // Appends another texture-space batch: its slots follow this batch's (texel.size() of them).
  void append(const Batch& other);
  // Keeps the rays for which keep(ray index) holds, in order (their slots unchanged).
  template <typename Keep>
  void keepRays(Keep keep) {
    size_t n = 0;
    for (size_t j = 0; j < rays.size(); ++j)
      if (keep(j)) rays[n] = rays[j], slot[n] = slot[j], object[n] = object[j], frame[n] = frame[j], ++n;
    rays.resize(n), slot.resize(n), object.resize(n), frame.resize(n);
    stats.rays = n;
  }
};

// What a training ray is compared with. A frame's pixel is the average of the radiance over its
// footprint. Point (the paper's, the default): the ray goes through the surface point itself and
// is compared with the bilinear interpolation of the frame there. Pixel: the ray goes through a
// uniformly random point of the (stored) pixel the surface point projects into and is compared
// with that pixel, so its expectation is the pixel (the frames' box filter); the adjoint pass
// goes through another, independent point of it (BatchRay::adjointDir). With Point, wherever the radiance varies within
// a pixel (a highlight on a curved glossy surface: a pixel of a 0.2 m ball 3 m away spans ~9 degrees of reflected
// directions, a roughness-0.1 lobe ~1) the pixel is a blur the point estimate must reproduce with a rougher material.
enum class RayFootprint { Pixel, Point };
template <>
struct EnumNames<RayFootprint> {
  static constexpr std::array<std::pair<RayFootprint, std::string_view>, 2> values{
      {{RayFootprint::Pixel, "pixel"}, {RayFootprint::Point, "point"}}};
};

struct TextureSamplerSettings {
  int texels = 16384;      // B: texels per iteration
  int framesPerTexel = 4;  // K: frame connections tried per texel
  RayFootprint footprint = RayFootprint::Point;
  // Rays per connection, each an independent estimate (the solver seeds each ray on its own); with
  // a pixel footprint each also draws its own points of the pixel.
  int samplesPerConnection = 1;
};

class TextureSpaceSampler {
 public:
  // `texels` are the sampleable texels of `map` (covered and observed); the sampler keeps a view
  // of them (as of the scene, map and index), not a copy.
  TextureSpaceSampler(const Scene& scene, const TexelMap& map, std::span<const uint32_t> texels,
                      const VisibilityIndex& vis, const TrainingFrames& frames);
  // A temporary list would be gone before the first sample.
  TextureSpaceSampler(const Scene&, const TexelMap&, std::vector<uint32_t>&&, const VisibilityIndex&,
                      const TrainingFrames&) = delete;
  Batch sample(uint64_t seed, uint64_t iteration, const TextureSamplerSettings& settings) const;
  size_t texelCount() const { return texels_.size(); }

 private:
  const Scene& scene_;
  const TexelMap& map_;
  std::span<const uint32_t> texels_;
  const VisibilityIndex& vis_;
  TrainingFrames frames_;
  std::vector<uint8_t> usable_;  // per frame index
};

// A uniformly random pixel of `cam` and the unit ray direction through it.
std::optional<std::pair<Vec2, Vec3>> randomPixelRay(const Camera& cam, Pcg32& rng);

class ImageSpaceSampler {
 public:
  explicit ImageSpaceSampler(const TrainingFrames& frames) : frames_(frames) {}
  // `rays` pixels drawn, `samples` rays each (as TextureSamplerSettings::samplesPerConnection).
  Batch sample(uint64_t seed, uint64_t iteration, int rays, const Scene& scene,
               RayFootprint footprint = RayFootprint::Point, int samples = 1) const;

 private:
  TrainingFrames frames_;
};

}  // namespace relume
