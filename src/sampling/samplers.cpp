#include "sampling/samplers.h"

#include <tbb/parallel_for.h>

#include <array>

#include "core/error.h"
#include "core/rng.h"
#include "core/random_streams.h"

namespace relume {

void SamplerStats::add(const SamplerStats& o) {
  slots += o.slots, candidates += o.candidates, notSeen += o.notSeen, firstHitElsewhere += o.firstHitElsewhere;
  masked += o.masked, disagreeing += o.disagreeing, rays += o.rays;
}

Json SamplerStats::toJson() const {
  return {{"slots", slots},      {"candidates", candidates},
          {"not_seen", notSeen}, {"first_hit_elsewhere", firstHitElsewhere},
          {"masked", masked},    {"disagreeing", disagreeing},
          {"rays", rays}};
}

void Batch::append(const Batch& other) {
  const auto slotOffset = static_cast<uint32_t>(texel.size());
  rays.insert(rays.end(), other.rays.begin(), other.rays.end());
  for (uint32_t s : other.slot) slot.push_back(slotOffset + s);
  object.insert(object.end(), other.object.begin(), other.object.end());
  frame.insert(frame.end(), other.frame.begin(), other.frame.end());
  texel.insert(texel.end(), other.texel.begin(), other.texel.end());
  stats.add(other.stats);
}

namespace {

// Slots are drawn in chunks, each written to its own batch (slot indices global) and joined in
// chunk order afterwards, so the batch does not depend on threads and a chunk, not a slot, owns
// the allocations.
constexpr size_t kChunkSlots = 32;

template <typename ChunkFn>
Batch sampleInChunks(size_t slots, ChunkFn&& sampleChunk) {
  std::vector<Batch> chunks((slots + kChunkSlots - 1) / kChunkSlots);
  tbb::parallel_for(size_t{0}, chunks.size(), [&](size_t c) {
    const size_t first = c * kChunkSlots;
    sampleChunk(first, std::min(kChunkSlots, slots - first), chunks[c]);
  });
  Batch b;
  size_t rays = 0, texels = 0;
  for (const Batch& c : chunks) rays += c.rays.size(), texels += c.texel.size();
  b.rays.reserve(rays), b.slot.reserve(rays), b.object.reserve(rays), b.frame.reserve(rays), b.texel.reserve(texels);
  for (const Batch& c : chunks) {
    b.rays.insert(b.rays.end(), c.rays.begin(), c.rays.end());
    b.slot.insert(b.slot.end(), c.slot.begin(), c.slot.end());
    b.object.insert(b.object.end(), c.object.begin(), c.object.end());
    b.frame.insert(b.frame.end(), c.frame.begin(), c.frame.end());
    b.texel.insert(b.texel.end(), c.texel.begin(), c.texel.end());
    b.stats.add(c.stats);
  }
  b.stats.rays = b.rays.size();
  return b;
}

// One slot's rays, appended to its chunk's batch.
struct SlotOutput {
  Batch& batch;
  uint32_t slot;
  int object = 0;  // of the targeted surface point; set before the first ray
  SamplerStats& stats() { return batch.stats; }
  BatchRay& add(const BatchRay& ray, uint32_t frame) {
    batch.slot.push_back(slot);
    batch.object.push_back(object);
    batch.frame.push_back(frame);
    return batch.rays.emplace_back(ray);
  }
};

ClipThresholds clipOf(const FrameStore& store, uint32_t frame) {
  return {store.stats(frame).clipLow, store.stats(frame).clipHigh};
}

// A ray whose expectation is the stored pixel: that pixel averages size x size frame pixels, each
// formed with the camera's filter, so a uniformly chosen one of them, then the filter around it.
std::optional<Vec3> randomDirectionIn(const Camera& cam, const FrameStore::StoredPixel& pixel, Pcg32& rng) {
  if (cam.filter.isUnitBox()) return cam.rayDirection(pixel.corner + pixel.size * rng.next2D());
  const auto offset = [&] {
    const float cell = std::floor(rng.next1D() * pixel.size);
    return cell + cam.filter.sample(rng.next1D());
  };
  const float dx = offset(), dy = offset();
  return cam.rayDirection(pixel.corner + Vec2(dx, dy));
}

// A pixel footprint's rays: `samples` rays compared with `pixel`, each through its own random
// point of it and with another, independent one for the adjoint pass (BatchRay::adjointDir).
// `first`, when given, is the first ray's primal direction, already drawn uniformly in the pixel.
void appendPixelRays(SlotOutput& out, uint32_t frame, const Camera& cam, const FrameStore::StoredPixel& pixel,
                     const ClipThresholds& clip, int samples, Pcg32& rng, std::optional<Vec3> first = std::nullopt) {
  for (int sample = 0; sample < samples; ++sample) {
    const auto primalDir = sample == 0 && first ? first : randomDirectionIn(cam, pixel, rng);
    const auto adjointDir = randomDirectionIn(cam, pixel, rng);
    if (!primalDir || !adjointDir) {  // outside the distortion model's valid domain
      ++out.stats().notSeen;
      return;
    }
    out.add(BatchRay{cam.position, *primalDir, pixel.value, clip}, frame).adjointDir = *adjointDir;
  }
}

}  // namespace

TextureSpaceSampler::TextureSpaceSampler(const Scene& scene, const TexelMap& map, std::span<const uint32_t> texels,
                                         const VisibilityIndex& vis, const TrainingFrames& frames)
    : scene_(scene), map_(map), texels_(texels), vis_(vis), frames_(frames), usable_(frames.frames->size(), 0) {
  if (map.resolution() % vis.resolution != 0)
    fail("texture sampler: resolution {} is not a multiple of the visibility index's {}", map.resolution(),
         vis.resolution);
  for (uint32_t f : frames.usable) usable_[f] = 1;
}

Batch TextureSpaceSampler::sample(uint64_t seed, uint64_t iteration, const TextureSamplerSettings& s) const {
  const TriangleMesh& mesh = scene_.mesh();
  // A texel's up to K frame connections (rng continues the slot's stream after the texel draw;
  // `candidates` is scratch space, reused so that a slot allocates nothing).
  const auto connect = [&](uint32_t texel, Pcg32& rng, std::vector<uint32_t>& candidates, SlotOutput& out) {
    const uint32_t tri = map_.triangle(texel);
    const Vec3 p = map_.point(mesh, texel), n = map_.normal(mesh, texel);  // as prepare tested visibility
    const size_t tile = vis_.tileOf(texel, map_.resolution());
    // Up to K distinct candidate frames, drawn without replacement (partial Fisher-Yates).
    candidates.assign(vis_.framesOf(tile), vis_.framesOf(tile) + vis_.frameCount(tile));
    const size_t k = std::min<size_t>(s.framesPerTexel, candidates.size());
    for (size_t i = 0; i < k; ++i) {
      std::swap(candidates[i], candidates[i + rng.nextU32() % (candidates.size() - i)]);
      const uint32_t f = candidates[i];
      if (!usable_[f]) continue;
      ++out.stats().candidates;
      const Camera& cam = (*frames_.frames)[f].camera;
      const auto px = inView(cam, p, n);
      if (!px) {
        ++out.stats().notSeen;
        continue;
      }
      frames_.store->prefetch(f, *px);  // its miss overlaps the traversal
      const Vec3 toPoint = p - cam.position;
      const float dist = toPoint.norm();
      const Vec3 dir = toPoint / dist;
      // The training ray must first hit this surface point: anything else (an occluder, or a
      // neighbouring surface at a grazing angle) would train the wrong texel.
      const RayHit hit = scene_.traverse(cam.position, dir);
      if (!hit.found() || hit.t < dist - 1e-3f * dist - 2 * rayEpsilon(p)) {
        ++out.stats().notSeen;
        continue;
      }
      if (hit.prim != tri && (cam.position + hit.t * dir - p).norm() > 1e-3f * dist + 2 * rayEpsilon(p)) {
        ++out.stats().firstHitElsewhere;
        continue;
      }
      if (s.footprint == RayFootprint::Point) {
        const auto reference = frames_.store->bilinear(f, *px);
        if (!reference) {
          ++out.stats().masked;
          continue;
        }
        for (int sample = 0; sample < s.samplesPerConnection; ++sample)
          out.add(BatchRay{cam.position, dir, *reference, clipOf(*frames_.store, f)}, f);
        continue;
      }
      const auto stored = frames_.store->pixelAt(f, *px);
      if (!stored) {
        ++out.stats().masked;
        continue;
      }
      appendPixelRays(out, f, cam, *stored, clipOf(*frames_.store, f), s.samplesPerConnection, rng);
    }
  };
  // A slot begins with a chain of dependent loads (texel list, texel map, triangle, its vertices,
  // the visibility tile) before its connections' traversals. Taken stage by stage over a chunk's
  // slots, the loads of one stage are independent, so their misses overlap (as in the renderer's
  // wavefront) instead of each slot waiting for its own.
  return sampleInChunks(texels_.empty() ? 0 : s.texels, [&](size_t first, size_t count, Batch& out) {
    std::array<Pcg32, kChunkSlots> rngs;
    std::array<uint32_t, kChunkSlots> texels;
    std::vector<uint32_t> candidates;
    for (size_t i = 0; i < count; ++i) {
      rngs[i] = Pcg32(hashTuple({seed, iteration, first + i, streamTag(RandomStream::TextureSampler)}));
      texels[i] = texels_[rngs[i].nextU32() % texels_.size()];
    }
    for (size_t i = 0; i < count; ++i) {
      const uint32_t tri = map_.triangle(texels[i]);
      __builtin_prefetch(&mesh.triangles[tri]);
      __builtin_prefetch(&mesh.faceObject[tri]);
      __builtin_prefetch(&vis_.offsets[vis_.tileOf(texels[i], map_.resolution())]);
    }
    for (size_t i = 0; i < count; ++i) {
      for (int v : mesh.triangles[map_.triangle(texels[i])]) {
        __builtin_prefetch(&mesh.positions[v]);
        __builtin_prefetch(&mesh.uvs[v]);
        if (!mesh.normals.empty()) __builtin_prefetch(&mesh.normals[v]);
      }
      __builtin_prefetch(vis_.framesOf(vis_.tileOf(texels[i], map_.resolution())));
    }
    for (size_t i = 0; i < count; ++i) {
      out.texel.push_back(texels[i]);
      SlotOutput slot{out, static_cast<uint32_t>(first + i), mesh.faceObject[map_.triangle(texels[i])]};
      ++slot.stats().slots;
      connect(texels[i], rngs[i], candidates, slot);
    }
  });
}

std::optional<std::pair<Vec2, Vec3>> randomPixelRay(const Camera& cam, Pcg32& rng) {
  const Vec2 u = rng.next2D();
  const Vec2 px(u.x() * cam.width, u.y() * cam.height);
  const auto dir = cam.rayDirection(px);
  if (!dir) return std::nullopt;
  return std::pair{px, *dir};
}

Batch ImageSpaceSampler::sample(uint64_t seed, uint64_t iteration, int rays, const Scene& scene, RayFootprint footprint,
                                int samples) const {
  const auto samplePixel = [&](size_t j, SlotOutput& out) {
    Pcg32 rng(hashTuple({seed, iteration, j, streamTag(RandomStream::ImageSampler)}));
    ++out.stats().slots, ++out.stats().candidates;
    const uint32_t f = frames_.usable[rng.nextU32() % frames_.usable.size()];
    const Frame& frame = (*frames_.frames)[f];
    const auto ray = randomPixelRay(frame.camera, rng);
    const RayHit hit = ray ? scene.traverse(frame.camera.position, ray->second) : RayHit{};
    if (!hit.found()) {
      ++out.stats().notSeen;
      return;
    }
    out.object = scene.mesh().faceObject[hit.prim];
    if (footprint == RayFootprint::Point) {
      const auto reference = frames_.store->bilinear(f, ray->first);
      if (!reference) {
        ++out.stats().masked;
        return;
      }
      for (int sample = 0; sample < samples; ++sample)
        out.add(BatchRay{frame.camera.position, ray->second, *reference, clipOf(*frames_.store, f)}, f);
      return;
    }
    // The pixel position is uniform in the image, so uniform within the pixel it falls in: with a
    // box filter it is the first sample's primal point.
    const auto stored = frames_.store->pixelAt(f, ray->first);
    if (!stored) {
      ++out.stats().masked;
      return;
    }
    appendPixelRays(out, f, frame.camera, *stored, clipOf(*frames_.store, f), samples, rng,
                    frame.camera.filter.isUnitBox() ? std::optional<Vec3>(ray->second) : std::nullopt);
  };
  return sampleInChunks(frames_.usable.empty() ? 0 : rays, [&](size_t first, size_t count, Batch& out) {
    for (size_t j = first; j < first + count; ++j) {
      SlotOutput slot{out, static_cast<uint32_t>(j)};
      samplePixel(j, slot);
    }
  });
}

}  // namespace relume
