// Gradient buffers mirroring an Appearance's unknowns, filled by passes over a batch of rays.
// Every sum is bit-identical at any thread count: a pass traces its rays in fixed chunks; each
// chunk logs its texel splats (bucketed by texel range) and sums its per-object terms in double;
// then every bucket applies the chunks' splats in chunk order and the per-object sums are added in
// chunk order. Each entry thus receives its terms in ray order, whichever thread traced them, so
// a fit gives the same result at 1 and at N threads (float atomics made the last bits depend on
// which thread added first).
#pragma once
#include <cstdint>
#include <functional>
#include <vector>

#include "scene/appearance.h"

namespace relume {

class Gradients {
 public:
  // withAlbedoCurvature: also allocate albedoCurvature (the Gauss-Newton albedo step needs it).
  explicit Gradients(const Appearance& shape, bool withAlbedoCurvature = false);
  // Zeroes the per-object sums and the texture entries splats reached since the last clear, no
  // others: every buffer is zero afterwards provided the texture buffers were written only by
  // accumulate, or set to zero (the fit's mask), never to another value by a caller.
  void clear();
  // The albedo texels whose gradient or curvature a splat reached since the last clear, each
  // once, in no particular order: every non-zero albedo gradient is at one of them, so a step or
  // mask over them costs the batch, not the texture.
  std::vector<uint32_t> splattedAlbedoTexels() const;
  size_t bookkeepingBytes() const;  // what tracking the splatted entries holds

  // What one chunk of a pass's rays writes; a chunk is traced by one thread at a time.
  class Chunk {
   public:
    void addAlbedo(uint32_t texel, const Color& g) { log(texel, g); }
    // Gauss-Newton curvature of the albedo texels (sum of w_t dI/da * dI/da over rays whose first
    // vertex reads texel t with bilinear weight w_t); dropped when the buffer was not allocated.
    bool hasCurvature() const { return !owner_->albedoCurvature.empty(); }
    void addAlbedoCurvature(uint32_t texel, const Color& h) {
      if (hasCurvature()) log(owner_->curvatureBase_ + texel, h);
    }
    void addEmissionTexel(int textureIndex, uint32_t texel, const Color& g) {
      log(owner_->emissionBase_[static_cast<size_t>(textureIndex)] + texel, g);
    }
    void addRoughness(int object, double g) { objects_[owner_->roughnessSlot(object)] += g; }
    void addSpecular(int object, double g) { objects_[owner_->specularSlot(object)] += g; }
    void addEmission(int object, const Color& g) {
      for (int c = 0; c < 3; ++c) objects_[owner_->emissionSlot(object, c)] += g[c];
    }

   private:
    friend class Gradients;
    struct Splat {
      uint32_t entry;  // texel in the concatenation [albedo | curvature | emission textures]
      Color value;
    };
    void log(uint32_t entry, const Color& v) { buckets_[entry >> owner_->bucketShift_].push_back({entry, v}); }
    const Gradients* owner_ = nullptr;
    std::vector<std::vector<Splat>> buckets_;
    std::vector<double> objects_;
  };

  // Runs trace(chunk, begin, end) over the rays [0, count) in chunks of kChunkRays, in parallel,
  // and adds every chunk's terms to the buffers below in chunk order. `splatVertices`: how many
  // path vertices of a ray may splat texels (1 when only the first vertex is differentiated, the
  // path length when every vertex is): the sub-batch shrinks with it, so the logs' memory does
  // not grow with the depth. The sub-batch changes when terms are applied, never their order.
  void accumulate(size_t count, const std::function<void(Chunk&, size_t, size_t)>& trace, size_t splatVertices = 1);
  // Bytes the splat logs hold (each bucket's capacity: the most it has held in one sub-batch,
  // with the vectors' growth slack).
  size_t logBytes() const;

  std::vector<float> albedo;           // texels * 3
  std::vector<float> albedoCurvature;  // texels * 3 like albedo, or empty
  std::vector<std::vector<float>> emissionTexture;
  std::vector<float> objects;  // [roughness | specular | emission rgb], slots:
  size_t roughnessSlot(int o) const { return static_cast<size_t>(o); }
  size_t specularSlot(int o) const { return static_cast<size_t>(objectCount_ + o); }
  size_t emissionSlot(int o, int c) const { return static_cast<size_t>(2 * objectCount_ + 3 * o + c); }

  static constexpr size_t kChunkRays = 256;  // fixed: the per-object sums are grouped by it

 private:
  // Rays traced before their splats are applied: bounds the logs' memory (constant per ray), at
  // one splatting vertex per ray; never fewer chunks than keep every core busy.
  static constexpr size_t kSubBatchRays = 64 * kChunkRays;
  static constexpr size_t kMinSubBatchChunks = 8;
  static constexpr uint32_t kBuckets = 64;
  void shareChunks(size_t firstChunk, size_t chunks);
  void apply(size_t chunks);
  float* texelData(uint32_t entry);

  int objectCount_;
  uint32_t curvatureBase_ = 0;
  std::vector<uint32_t> emissionBase_;
  int bucketShift_ = 0;
  size_t bucketCount_ = 1;
  std::vector<Chunk> chunks_;                           // one sub-batch's, reused
  std::vector<uint8_t> splatted_;                       // per entry: reached since the last clear
  std::vector<std::vector<uint32_t>> splattedEntries_;  // per bucket: those entries
};

}  // namespace relume
