#include "params/gradients.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cstring>

#include "core/check.h"
#include "core/error.h"
#include "core/ranks.h"

namespace relume {

Gradients::Gradients(const Appearance& shape, bool withAlbedoCurvature)
    : albedo(shape.albedo.rgb.size(), 0.0f),
      albedoCurvature(withAlbedoCurvature ? shape.albedo.rgb.size() : 0, 0.0f),
      objects(5 * static_cast<size_t>(shape.objectCount()), 0.0f),
      objectCount_(shape.objectCount()) {
  for (const Texture& t : shape.emissionTextures) emissionTexture.emplace_back(t.rgb.size(), 0.0f);
  uint64_t texels = albedo.size() / 3;
  curvatureBase_ = static_cast<uint32_t>(texels);
  texels += albedoCurvature.size() / 3;
  for (const auto& t : emissionTexture) {
    emissionBase_.push_back(static_cast<uint32_t>(texels));
    texels += t.size() / 3;
  }
  if (texels > UINT32_MAX) fail("gradient buffers: {} texels exceed 2^32", texels);
  // Buckets of whole powers of two, at most kBuckets of them.
  const uint64_t perBucket = std::max<uint64_t>(1, (texels + kBuckets - 1) / kBuckets);
  bucketShift_ = std::bit_width(perBucket - 1);
  bucketCount_ = texels == 0 ? 1 : ((texels - 1) >> bucketShift_) + 1;
  splatted_.assign(texels, 0);
  splattedEntries_.resize(bucketCount_);
}

void Gradients::clear() {
  // Only the entries splats reached can be non-zero: clearing them costs the batch, not the
  // texture (tens of MiB at 4K).
  tbb::parallel_for(size_t{0}, bucketCount_, [&](size_t b) {
    for (uint32_t entry : splattedEntries_[b]) {
      std::fill_n(texelData(entry), 3, 0.0f);
      splatted_[entry] = 0;
    }
    splattedEntries_[b].clear();
  });
  std::fill(objects.begin(), objects.end(), 0.0f);
}

std::vector<uint32_t> Gradients::splattedAlbedoTexels() const {
  std::vector<uint32_t> texels;
  for (const auto& entries : splattedEntries_)
    for (uint32_t e : entries) {
      if (e < curvatureBase_) texels.push_back(e);
      // A curvature entry adds its texel unless the texel's gradient entry already did.
      else if (e - curvatureBase_ < albedoCurvature.size() / 3 && !splatted_[e - curvatureBase_])
        texels.push_back(e - curvatureBase_);
    }
  return texels;
}

size_t Gradients::bookkeepingBytes() const {
  size_t bytes = splatted_.capacity();
  for (const auto& entries : splattedEntries_) bytes += entries.capacity() * sizeof(uint32_t);
  return bytes;
}

float* Gradients::texelData(uint32_t entry) {
  if (entry < curvatureBase_) return albedo.data() + 3 * static_cast<size_t>(entry);
  const auto texture = std::upper_bound(emissionBase_.begin(), emissionBase_.end(), entry);
  if (texture == emissionBase_.begin()) return albedoCurvature.data() + 3 * static_cast<size_t>(entry - curvatureBase_);
  const size_t t = static_cast<size_t>(texture - emissionBase_.begin()) - 1;
  return emissionTexture[t].data() + 3 * static_cast<size_t>(entry - emissionBase_[t]);
}

void Gradients::accumulate(size_t count, const std::function<void(Chunk&, size_t, size_t)>& trace,
                           size_t splatVertices) {
  if (chunks_.empty()) {
    chunks_.resize(kSubBatchRays / kChunkRays);
    for (Chunk& c : chunks_) {
      c.buckets_.resize(bucketCount_);
      c.objects_.assign(objects.size(), 0.0);
    }
  }
  for (Chunk& c : chunks_) c.owner_ = this;  // this object may have moved since
  std::vector<double> objectSum(objects.size(), 0.0);
  const size_t subBatch =
      kChunkRays * std::max(kMinSubBatchChunks, chunks_.size() / std::max<size_t>(1, splatVertices));
  for (size_t first = 0; first < count; first += subBatch) {
    const size_t last = std::min(count, first + subBatch);
    const size_t chunks = (last - first + kChunkRays - 1) / kChunkRays;
    CHECK(chunks <= chunks_.size());  // every chunk of a sub-batch has its own log
    const size_t firstChunk = first / kChunkRays;
    tbb::parallel_for(size_t{0}, chunks, [&](size_t c) {
      if (!Ranks::world().ownsChunk(firstChunk + c)) return;  // another rank's (core/ranks.h)
      const size_t begin = first + c * kChunkRays;
      trace(chunks_[c], begin, std::min(last, begin + kChunkRays));
    });
    shareChunks(firstChunk, chunks);
    apply(chunks);
    for (size_t c = 0; c < chunks; ++c) {
      for (size_t i = 0; i < objectSum.size(); ++i) objectSum[i] += chunks_[c].objects_[i];
      std::fill(chunks_[c].objects_.begin(), chunks_[c].objects_.end(), 0.0);
    }
  }
  for (size_t i = 0; i < objects.size(); ++i) objects[i] += static_cast<float>(objectSum[i]);
}

// Over MPI ranks: each rank's chunks' logs and per-object sums, to every rank, so that each applies
// every chunk's in chunk order as one process would. Only the splats travel: the entries the
// batch reached, not the texture.
void Gradients::shareChunks(size_t firstChunk, size_t chunks) {
  Ranks& ranks = Ranks::world();
  if (!ranks.distributed()) return;
  std::vector<uint8_t> mine;
  auto put = [&](const void* p, size_t n) {
    mine.insert(mine.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
  };
  for (size_t c = 0; c < chunks; ++c) {
    if (!ranks.ownsChunk(firstChunk + c)) continue;
    const Chunk& chunk = chunks_[c];
    const uint32_t index = static_cast<uint32_t>(c);
    put(&index, sizeof index);
    for (const auto& splats : chunk.buckets_) {
      const uint32_t n = static_cast<uint32_t>(splats.size());
      put(&n, sizeof n);
      put(splats.data(), n * sizeof(Chunk::Splat));
    }
    uint32_t nonZero = 0;
    for (double v : chunk.objects_) nonZero += v != 0.0;
    put(&nonZero, sizeof nonZero);
    for (uint32_t i = 0; i < chunk.objects_.size(); ++i)
      if (chunk.objects_[i] != 0.0) put(&i, sizeof i), put(&chunk.objects_[i], sizeof(double));
  }
  const std::vector<std::vector<uint8_t>> all = ranks.allGather(mine);
  for (int r = 0; r < ranks.size(); ++r) {
    if (r == ranks.rank()) continue;
    const std::vector<uint8_t>& in = all[static_cast<size_t>(r)];
    size_t at = 0;
    auto get = [&](void* p, size_t n) {
      if (n == 0) return;  // an empty bucket's data() may be null, which memcpy must not be given
      CHECK(at + n <= in.size());  // every rank writes the layout above
      std::memcpy(p, in.data() + at, n);
      at += n;
    };
    while (at < in.size()) {
      uint32_t index = 0, n = 0, nonZero = 0;
      get(&index, sizeof index);
      CHECK(index < chunks && !ranks.ownsChunk(firstChunk + index));
      Chunk& chunk = chunks_[index];
      for (auto& splats : chunk.buckets_) {
        get(&n, sizeof n);
        splats.resize(n);
        get(splats.data(), n * sizeof(Chunk::Splat));
      }
      get(&nonZero, sizeof nonZero);
      for (uint32_t k = 0; k < nonZero; ++k) {
        uint32_t i = 0;
        get(&i, sizeof i);
        CHECK(i < chunk.objects_.size());
        get(&chunk.objects_[i], sizeof(double));
      }
    }
  }
}

void Gradients::apply(size_t chunks) {
  tbb::parallel_for(size_t{0}, bucketCount_, [&](size_t b) {
    for (size_t c = 0; c < chunks; ++c) {
      auto& splats = chunks_[c].buckets_[b];
      for (const Chunk::Splat& s : splats) {
        DCHECK(s.entry < splatted_.size());
        float* d = texelData(s.entry);
        for (int k = 0; k < 3; ++k) d[k] += s.value[k];
        if (!splatted_[s.entry]) splatted_[s.entry] = 1, splattedEntries_[b].push_back(s.entry);  // bucket b's alone
      }
      splats.clear();
    }
  });
}

size_t Gradients::logBytes() const {
  size_t bytes = 0;
  for (const Chunk& c : chunks_)
    for (const auto& b : c.buckets_) bytes += b.capacity() * sizeof(Chunk::Splat);
  return bytes;
}

}  // namespace relume
