#include "sampling/samplers.h"

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "core/rng.h"

namespace relume {

void SamplerStats::add(const SamplerStats& o) {
  slots += o.slots, candidates += o.candidates, notSeen += o.notSeen, firstHitElsewhere += o.firstHitElsewhere;
  masked += o.masked, rays += o.rays;
}

void Batch::append(const Batch& other) {
  const auto slotOffset = static_cast<uint32_t>(texel.size());
  rays.insert(rays.end(), other.rays.begin(), other.rays.end());
  for (uint32_t s : other.slot) slot.push_back(slotOffset + s);
  object.insert(object.end(), other.object.begin(), other.object.end());
  texel.insert(texel.end(), other.texel.begin(), other.texel.end());
  stats.add(other.stats);
}

namespace {

// Per-slot output, compacted in slot order afterwards so the batch does not depend on threads.
struct SlotRays {
  std::vector<BatchRay> rays;
  int object = 0;
  uint32_t texel = 0;
  SamplerStats stats;
};

Batch compact(std::vector<SlotRays>& slots, bool texels) {
  Batch b;
  for (size_t s = 0; s < slots.size(); ++s) {
    if (texels) b.texel.push_back(slots[s].texel);
    for (BatchRay& r : slots[s].rays) {
      b.rays.push_back(r);
      b.slot.push_back(static_cast<uint32_t>(s));
      b.object.push_back(slots[s].object);
    }
    b.stats.add(slots[s].stats);
  }
  b.stats.rays = b.rays.size();
  return b;
}

ClipThresholds clipOf(const Frame& f) { return {f.clipLow, f.clipHigh}; }

// A ray whose expectation is the stored pixel: that pixel averages size x size frame pixels, each
// formed with the camera's filter, so a uniformly chosen one of them, then the filter around it.
std::optional<Vec3> randomDirectionIn(const Camera& cam, const FrameStore::StoredPixel& pixel, Pcg32& rng) {
  if (cam.filter.isUnitBox()) return cam.rayDirection(pixel.corner + pixel.size * Vec2(rng.next1D(), rng.next1D()));
  const auto offset = [&] { return std::floor(rng.next1D() * pixel.size) + cam.filter.sample(rng.next1D()); };
  const float dx = offset(), dy = offset();
  return cam.rayDirection(pixel.corner + Vec2(dx, dy));
}

// A pixel footprint's rays: `samples` rays compared with `pixel`, each through its own random
// point of it and with another, independent one for the adjoint pass (BatchRay::adjointDir).
// `first`, when given, is the first ray's primal direction, already drawn uniformly in the pixel.
void appendPixelRays(SlotRays& out, const Camera& cam, const FrameStore::StoredPixel& pixel, const ClipThresholds& clip,
                     int samples, Pcg32& rng, std::optional<Vec3> first = std::nullopt) {
  for (int sample = 0; sample < samples; ++sample) {
    const auto primalDir = sample == 0 && first ? first : randomDirectionIn(cam, pixel, rng);
    const auto adjointDir = randomDirectionIn(cam, pixel, rng);
    if (!primalDir || !adjointDir) {  // outside the distortion model's valid domain
      ++out.stats.notSeen;
      return;
    }
    BatchRay& ray = out.rays.emplace_back(BatchRay{cam.position, *primalDir, pixel.value, clip});
    ray.adjointDir = *adjointDir;
  }
}

}  // namespace

RayFootprint parseRayFootprint(const std::string& name) {
  if (name == "pixel") return RayFootprint::Pixel;
  if (name == "point") return RayFootprint::Point;
  fail("ray footprint '{}': must be pixel or point", name);
}

TextureSpaceSampler::TextureSpaceSampler(const Scene& scene, const TexelMap& map, std::vector<uint32_t> texels,
                                         const VisibilityIndex& vis, const TrainingFrames& frames)
    : scene_(scene), map_(map), texels_(std::move(texels)), vis_(vis), frames_(frames), usable_(frames.frames->size(), 0) {
  if (map.resolution() % vis.resolution != 0)
    fail("texture sampler: resolution {} is not a multiple of the visibility index's {}", map.resolution(), vis.resolution);
  for (uint32_t f : frames.usable) usable_[f] = 1;
}

Batch TextureSpaceSampler::sample(uint64_t seed, uint64_t iteration, const TextureSamplerSettings& s) const {
  std::vector<SlotRays> slots(texels_.empty() ? 0 : s.texels);
  const TriangleMesh& mesh = scene_.mesh();
  tbb::parallel_for(size_t{0}, slots.size(), [&](size_t j) {
    Pcg32 rng(hashTuple({seed, iteration, j, 0x7473}));
    SlotRays& out = slots[j];
    out.stats.slots = 1;
    const uint32_t texel = out.texel = texels_[rng.nextU32() % texels_.size()];
    const uint32_t tri = map_.triangle(texel);
    out.object = mesh.faceObject[tri];
    const Vec3 p = map_.point(mesh, texel), n = map_.normal(mesh, texel);  // as prepare tested visibility
    const size_t tile = vis_.tileOf(texel, map_.resolution());
    // Up to K distinct candidate frames, drawn without replacement (partial Fisher-Yates).
    const uint32_t* list = vis_.framesOf(tile);
    std::vector<uint32_t> candidates(list, list + vis_.frameCount(tile));
    const size_t k = std::min<size_t>(s.framesPerTexel, candidates.size());
    for (size_t i = 0; i < k; ++i) {
      std::swap(candidates[i], candidates[i + rng.nextU32() % (candidates.size() - i)]);
      const uint32_t f = candidates[i];
      if (!usable_[f]) continue;
      ++out.stats.candidates;
      const Frame& frame = (*frames_.frames)[f];
      const Camera& cam = frame.camera;
      const auto px = inView(cam, p, n);
      if (!px) {
        ++out.stats.notSeen;
        continue;
      }
      const Vec3 toPoint = p - cam.position;
      const float dist = toPoint.norm();
      const Vec3 dir = toPoint / dist;
      // The training ray must first hit this surface point: anything else (an occluder, or a
      // neighbouring surface at a grazing angle) would train the wrong texel.
      const auto hit = scene_.intersect(cam.position, dir);
      if (!hit || hit->t < dist - 1e-3f * dist - 2 * rayEpsilon(p)) {
        ++out.stats.notSeen;
        continue;
      }
      if (hit->prim != tri && (hit->p - p).norm() > 1e-3f * dist + 2 * rayEpsilon(p)) {
        ++out.stats.firstHitElsewhere;
        continue;
      }
      if (s.footprint == RayFootprint::Point) {
        const auto reference = frames_.store->bilinear(f, *px);
        if (!reference) {
          ++out.stats.masked;
          continue;
        }
        out.rays.insert(out.rays.end(), s.samplesPerConnection, BatchRay{cam.position, dir, *reference, clipOf(frame)});
        continue;
      }
      const auto stored = frames_.store->pixelAt(f, *px);
      if (!stored) {
        ++out.stats.masked;
        continue;
      }
      appendPixelRays(out, cam, *stored, clipOf(frame), s.samplesPerConnection, rng);
    }
  });
  return compact(slots, true);
}

std::optional<std::pair<Vec2, Vec3>> randomPixelRay(const Camera& cam, Pcg32& rng) {
  const Vec2 px(rng.next1D() * cam.width, rng.next1D() * cam.height);
  const auto dir = cam.rayDirection(px);
  if (!dir) return std::nullopt;
  return std::pair{px, *dir};
}

Batch ImageSpaceSampler::sample(uint64_t seed, uint64_t iteration, int rays, const Scene& scene, RayFootprint footprint,
                                int samples) const {
  std::vector<SlotRays> slots(frames_.usable.empty() ? 0 : rays);
  tbb::parallel_for(size_t{0}, slots.size(), [&](size_t j) {
    Pcg32 rng(hashTuple({seed, iteration, j, 0x6973}));
    SlotRays& out = slots[j];
    out.stats.slots = out.stats.candidates = 1;
    const uint32_t f = frames_.usable[rng.nextU32() % frames_.usable.size()];
    const Frame& frame = (*frames_.frames)[f];
    const auto ray = randomPixelRay(frame.camera, rng);
    const auto hit = ray ? scene.intersect(frame.camera.position, ray->second) : std::nullopt;
    if (!hit) {
      ++out.stats.notSeen;
      return;
    }
    out.object = hit->object;
    if (footprint == RayFootprint::Point) {
      const auto reference = frames_.store->bilinear(f, ray->first);
      if (!reference) {
        ++out.stats.masked;
        return;
      }
      out.rays.insert(out.rays.end(), samples, BatchRay{frame.camera.position, ray->second, *reference, clipOf(frame)});
      return;
    }
    // The pixel position is uniform in the image, so uniform within the pixel it falls in: with a
    // box filter it is the first sample's primal point.
    const auto stored = frames_.store->pixelAt(f, ray->first);
    if (!stored) {
      ++out.stats.masked;
      return;
    }
    appendPixelRays(out, frame.camera, *stored, clipOf(frame), samples, rng,
                    frame.camera.filter.isUnitBox() ? std::optional<Vec3>(ray->second) : std::nullopt);
  });
  return compact(slots, false);
}

}  // namespace relume
