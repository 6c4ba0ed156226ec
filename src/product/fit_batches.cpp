#include "product/fit_batches.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "core/random_streams.h"
#include "core/rng.h"
#include "product/confidence.h"
#include "product/frame_gains.h"
#include "product/light_evidence.h"
#include "sampling/samplers.h"

namespace relume {

FitBatches::FitBatches(const FitConfig& c, const Workspace& w) : c_(c), w_(w) {
  if (!c_.dropDisagreeing) return;
  median_ = w_.medianRadiance();
  // prepare divided the frames by its gains before the median where frame_gains auto would estimate them.
  if (resolveFrameGains(FrameGainMode::Auto, w_.frames, *w_.store, w_.kept) != FrameGainMode::None)
    gains_ = w_.consistencyGains();
}

void FitBatches::dropDisagreeing(const TexelSpace& space, Batch& b) const {
  const int perInit = space.resolution / w_.initResolution;
  const float threshold = std::log(kAgreementRatio);
  const FrameStore& store = *w_.store;
  std::vector<uint8_t> keep(b.rays.size(), 1);
  tbb::parallel_for(size_t{0}, b.rays.size(), [&](size_t j) {
    const uint32_t texel = b.texel[b.slot[j]];
    if (w_.coverageOf(texel, space.resolution) < kFewObservations) return;  // no consensus to disagree with
    const BatchRay& r = b.rays[j];
    const FrameStats& s = store.stats(b.frame[j]);
    if ((r.reference >= s.clipHigh).any() || (r.reference <= s.clipLow).all()) return;  // a bound, not a value
    const int x = static_cast<int>(texel % space.resolution) / perInit,
              y = static_cast<int>(texel / space.resolution) / perInit;
    const Color observed = gains_.empty() ? r.reference : Color(r.reference / gains_[b.frame[j]]);
    keep[j] = observationDeviation(observed, median_.at(x, y)) <= threshold;
  });
  const size_t before = b.rays.size();
  b.keepRays([&](size_t j) { return keep[j] != 0; });
  b.stats.disagreeing += before - b.rays.size();
}

Batch FitBatches::sample(const TexelSpace& space, uint64_t iteration, RayFootprint footprint,
                         const BatchFocus& focus) const {
  if (c_.sampler != SamplerKind::Texture)
    return ImageSpaceSampler(w_.trainingFrames())
        .sample(c_.seed, iteration, c_.imageRays, *w_.scene, footprint, c_.samplesPerRay);
  const TextureSpaceSampler sampler(*w_.scene, space.map, space.sampleable, w_.vis, w_.trainingFrames());
  Batch b = sampler.sample(c_.seed, iteration, {c_.batchTexels, c_.framesPerTexel, footprint, c_.samplesPerRay});
  if (c_.dropDisagreeing) dropDisagreeing(space, b);
  auto add = [&](const std::vector<uint32_t>& texels, int count, RayFootprint fp, uint64_t stream) {
    if (texels.empty() || count == 0) return;
    const TextureSpaceSampler focused(*w_.scene, space.map, texels, w_.vis, w_.trainingFrames());
    b.append(focused.sample(hashTuple({c_.seed, stream}), iteration, {count, c_.framesPerTexel, fp, c_.samplesPerRay}));
  };
  add(focus.objects, c_.materialBatchTexels, c_.materialFootprint, streamTag(RandomStream::MaterialBatch));
  add(focus.highlights, c_.highlightBatchTexels, c_.materialFootprint, streamTag(RandomStream::HighlightBatch));
  const int perCandidate = focus.candidates.empty()
                               ? 0
                               : std::max<int>(1, c_.emissionBatchTexels / static_cast<int>(focus.candidates.size()));
  for (size_t i = 0; i < focus.candidates.size(); ++i)
    add(focus.candidates[i], perCandidate, footprint, hashTuple({streamTag(RandomStream::EmissionBatch), i}));
  return b;
}

BatchFocus FitBatches::materialFocus(const TexelSpace& space, const std::vector<uint8_t>& fitted,
                                     const Appearance& appearance, const std::vector<uint8_t>& emitter) const {
  BatchFocus f;
  for (uint32_t t : space.sampleable)
    if (fitted[space.objectOf(t, w_.mesh)]) f.objects.push_back(t);
  if (f.objects.empty() || c_.highlightBatchTexels == 0) return f;
  const TextureSpaceSampler all(*w_.scene, space.map, f.objects, w_.vis, w_.trainingFrames());
  const int draws = static_cast<int>(std::min<size_t>(8 * f.objects.size(), 1 << 24));
  const Batch b = all.sample(hashTuple({c_.seed, streamTag(RandomStream::HighlightProbe)}), 0,
                             {draws, 1 << 20, RayFootprint::Point});
  std::vector<uint8_t> lit(space.map.texelCount(), 0);
  tbb::parallel_for(size_t{0}, b.rays.size(), [&](size_t j) {
    if (seesLightReflected(*w_.scene, appearance, emitter, b.rays[j]) == 1)
      lit[b.texel[b.slot[j]]] = 1;  // benign race: every writer stores 1
  });
  for (uint32_t t : f.objects)
    if (lit[t]) f.highlights.push_back(t);
  spdlog::info("fit: {} of the fitted objects' {} texels show a light reflected", f.highlights.size(),
               f.objects.size());
  return f;
}

BatchFocus FitBatches::emissionFocus(const TexelSpace& space, const std::vector<uint8_t>& emitter) const {
  BatchFocus f;
  if (c_.emissionBatchTexels == 0) return f;
  std::vector<std::vector<uint32_t>> texels = space.sampleableByObject(w_.mesh, static_cast<int>(emitter.size()));
  for (size_t o = 0; o < emitter.size(); ++o)
    if (emitter[o] && !texels[o].empty()) f.candidates.push_back(std::move(texels[o]));
  return f;
}

int8_t seesLightReflected(const Scene& scene, const Appearance& appearance, const std::vector<uint8_t>& emitter,
                          const BatchRay& r) {
  if (!(r.reference.minCoeff() >= 0)) return -1;
  const auto hit = scene.intersect(r.origin, r.dir);
  if (!hit) return -1;
  int8_t seen = 0;
  forEachMirrorDirection(*hit, r.dir, [&](const Vec3& d) {
    const auto light = scene.intersect(Scene::offsetOrigin(*hit, d), d);
    if (light && emitter[light->object] && appearance.isEmissive(light->object) && light->ng.dot(d) < 0) seen = 1;
    return seen == 0;
  });
  return seen;
}

}  // namespace relume
