#include "adjoint/solver.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/check.h"
#include "core/error.h"
#include "core/system.h"
#include "core/random_streams.h"
#include "core/ranks.h"

namespace relume {

uint64_t primalSeed(const AdjointSettings& s, uint64_t iteration, size_t ray) {
  return hashTuple({s.seed, iteration, ray, streamTag(RandomStream::PrimalPass)});
}
uint64_t adjointSeed(const AdjointSettings& s, uint64_t iteration, size_t ray) {
  return hashTuple({s.seed, iteration, ray, streamTag(RandomStream::AdjointPass)});
}

namespace {

// Fixed-size record of one path vertex x_k: everything the backward sweep needs.
struct VertexRecord {
  int object;
  Vec2 uv;
  Vec3 wo;
  BsdfParams params;
  Color beta;     // throughput from the camera to x_k (detached)
  Color emitted;  // mis * Le at x_k, reached from x_{k-1}
  float emitMis;
  bool frontFacing;
  bool hasNee;
  Vec3 neeWi;
  Color neeF, neeLe;
  float neeCos, neeScale;  // scale = mis / pdf_light
  int lightObject;
  Vec2 lightUv;
  bool hasScatter;
  Vec3 wi;
  Color f;
  float cos, pdf, survival;
};

struct AdjointRecorder : NullPathObserver {
  static constexpr bool kDifferentiating = true;
  const Appearance* appearance = nullptr;
  VertexRecord* records = nullptr;
  int count = 0;

  void vertex(int depth, const SurfaceHit& hit, const ShadingFrame&, const Vec3& wo, const Color& beta) {
    VertexRecord& r = records[depth];
    r.object = hit.object;
    r.uv = hit.uv;
    r.wo = wo;
    r.params = bsdfParamsAt(*appearance, hit);
    r.beta = beta;
    r.emitted = Color::Zero();
    r.emitMis = 0.0f;
    r.frontFacing = false;
    r.hasNee = r.hasScatter = false;
    count = depth + 1;
  }
  void emission(int depth, const SurfaceHit&, float mis, const Color& le) {
    VertexRecord& r = records[depth];
    r.emitted = mis * le;
    r.emitMis = mis;
    r.frontFacing = true;
  }
  void nee(int depth, const Vec3& wi, const Color& f, float cosI, float scale, const Color& le,
           const SurfaceHit& light) {
    VertexRecord& r = records[depth];
    r.hasNee = true;
    r.neeWi = wi, r.neeF = f, r.neeLe = le, r.neeCos = cosI, r.neeScale = scale;
    r.lightObject = light.object;
    r.lightUv = light.uv;
  }
  void scatter(int depth, const Vec3& wi, const Color& f, float cosI, float pdf, float survival) {
    VertexRecord& r = records[depth];
    r.hasScatter = true;
    r.wi = wi, r.f = f, r.cos = cosI, r.pdf = pdf, r.survival = survival;
  }
};

class Scatterer {
 public:
  static constexpr bool kScatters = true;
  Scatterer(const Appearance& a, const AdjointSettings& s, Gradients::Chunk& g) : a_(a), s_(s), g_(g) {}

  void bsdf(const VertexRecord& r, const BsdfEval& d, const Color& w) {
    // w: per-channel weight of df (delta * beta * the term's radiance factor).
    if (s_.mask.active(ParamKind::Albedo) && a_.usesTexture(r.object)) {
      const Color g = d.dAlbedo * w;
      const TexelFootprint fp = a_.albedo.footprint(r.uv);
      for (int k = 0; k < 4; ++k)
        if (fp.weight[k] != 0.0f) g_.addAlbedo(fp.index[k], fp.weight[k] * g);
    }
    if (s_.mask.active(ParamKind::Roughness)) g_.addRoughness(r.object, (d.dRoughness * w).sum());
    if (s_.mask.active(ParamKind::Specular)) g_.addSpecular(r.object, (d.dSpecular * w).sum());
  }
  // Row-sum Gauss-Newton curvature of the texels under the first vertex: weight x w_t X X', the
  // product of two independent estimates of the ray's albedo sensitivity X (an unbiased X^2).
  // A path that hit nothing has no first vertex (its record would be another ray's).
  void albedoCurvature(const AdjointRecorder& path, const Color& h) {
    if (!g_.hasCurvature() || path.count == 0 || (h == 0.0f).all() || !s_.mask.active(ParamKind::Albedo)) return;
    const VertexRecord& r = path.records[0];
    if (!a_.usesTexture(r.object)) return;
    const TexelFootprint fp = a_.albedo.footprint(r.uv);
    for (int k = 0; k < 4; ++k)
      if (fp.weight[k] != 0.0f) g_.addAlbedoCurvature(fp.index[k], fp.weight[k] * h);
  }
  void emission(int object, const Vec2& uv, const Color& g) {
    if (const Texture* t = a_.emissionTexture(object)) {
      if (!s_.mask.active(ParamKind::EmissionTexture)) return;
      const TexelFootprint fp = t->footprint(uv);
      for (int k = 0; k < 4; ++k)
        if (fp.weight[k] != 0.0f) g_.addEmissionTexel(a_.emissionTextureOf[object], fp.index[k], fp.weight[k] * g);
    } else if (s_.mask.active(ParamKind::Emission)) {
      g_.addEmission(object, g);
    }
  }

 private:
  const Appearance& a_;
  const AdjointSettings& s_;
  Gradients::Chunk& g_;
};

// What the primal pass keeps of a sweep: nothing but the first vertex's albedo sensitivity.
struct NoScatter {
  static constexpr bool kScatters = false;
  void bsdf(const VertexRecord&, const BsdfEval&, const Color&) {}
  void emission(int, const Vec2&, const Color&) {}
};

// Backward sweep over one cached path, scattering delta x derivative. Returns dI/d(albedo) at the
// first vertex (per channel, zero if it has no diffuse lobe): the Gauss-Newton sensitivity.
template <typename Out>
Color sweep(const VertexRecord* records, int count, const Color& delta, const AdjointSettings& settings, Out& out) {
  Color arriving = Color::Zero();  // radiance arriving at x_k along its BSDF sample (suffix sum)
  Color dIdAlbedo = Color::Zero();
  for (int k = count - 1; k >= 0; --k) {
    const VertexRecord& r = records[k];
    const Color after = r.hasScatter ? arriving : Color::Zero();
    const Color throughput = r.hasScatter ? Color(r.f * (r.cos / (r.pdf * r.survival))) : Color::Zero();
    const Color neeRadiance = r.hasNee ? Color(r.neeF * (r.neeCos * r.neeScale) * r.neeLe) : Color::Zero();
    const Color db = delta * r.beta;
    if (k == 0 || (Out::kScatters && settings.bsdfGradientAt(k))) {
      if (r.hasNee) {
        const BsdfEval d = evalBsdf(r.params, r.wo, r.neeWi, kBsdfDerivatives);
        const Color radiance = r.beta * (r.neeCos * r.neeScale) * r.neeLe;
        if (settings.bsdfGradientAt(k)) out.bsdf(r, d, delta * radiance);
        if (k == 0) dIdAlbedo += d.dAlbedo * radiance;
      }
      if (r.hasScatter && after.maxCoeff() > 0.0f) {
        const BsdfEval d = evalBsdf(r.params, r.wo, r.wi, kBsdfDerivatives);
        const Color radiance = r.beta * (r.cos / (r.pdf * r.survival)) * after;
        if (settings.bsdfGradientAt(k)) out.bsdf(r, d, delta * radiance);
        if (k == 0) dIdAlbedo += d.dAlbedo * radiance;
      }
    }
    if (Out::kScatters) {
      if (r.frontFacing && settings.emissionGradientFrom(k - 1)) out.emission(r.object, r.uv, db * r.emitMis);
      if (r.hasNee && settings.emissionGradientFrom(k))
        out.emission(r.lightObject, r.lightUv, db * r.neeF * (r.neeCos * r.neeScale));
    }
    arriving = r.emitted + neeRadiance + throughput * after;
  }
  return dIdAlbedo;
}

// Per-thread record buffers: kRecordedWaves waves of wavePaths(depth) paths of up to depth + 1
// vertices each, a bounded size whatever the batch: constant memory per ray.
class RecordBuffers {
 public:
  explicit RecordBuffers(int maxDepth)
      : n_(static_cast<size_t>(maxDepth + 1)),
        width_(wavePaths(maxDepth)),
        buffers_([this] { return std::vector<VertexRecord>(kRecordedWaves * width_ * n_); }) {}
  VertexRecord* get(int wave) { return buffers_.local().data() + wave * width_ * n_; }
  size_t width() const { return width_; }
  size_t stride() const { return n_; }

 private:
  size_t n_, width_;
  tbb::enumerable_thread_specific<std::vector<VertexRecord>> buffers_;
};

// Paths traced together as one wavefront (render/path_tracer.h), each recorded into its own slice
// of one of a thread's record buffers.
class RecordedWave {
 public:
  RecordedWave(const Appearance& appearance, RecordBuffers& buffers, int wave)
      : appearance_(appearance), records_(buffers.get(wave)), stride_(buffers.stride()) {
    paths_.reserve(buffers.width());
    recorders_.reserve(buffers.width());
  }
  void clear() { paths_.clear(), recorders_.clear(); }
  void add(const Vec3& origin, const Vec3& dir, uint64_t seed) {
    AdjointRecorder& r = recorders_.emplace_back();
    r.appearance = &appearance_;
    r.records = records_ + recorders_.size() * stride_ - stride_;
    paths_.emplace_back(origin, dir, Pcg32(seed));
  }
  void trace(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope, const PathSettings& path) {
    tracePaths(scene, lights, scope, path, std::span<PathSlot>(paths_),
               [this](size_t i) -> AdjointRecorder& { return recorders_[i]; });
  }
  const Color& radiance(size_t i) const { return paths_[i].L; }
  const AdjointRecorder& path(size_t i) const { return recorders_[i]; }

 private:
  const Appearance& appearance_;
  VertexRecord* records_;
  size_t stride_;
  std::vector<PathSlot> paths_;
  std::vector<AdjointRecorder> recorders_;
};

Color safeRadiance(const Color& c) { return isFinite(c) ? c : Color::Zero(); }

// body(begin, end) over the chunks of [0, count) this rank traces (all of them in one process), in
// parallel; every ray's result depends on its index alone, so the split never changes it.
void forOwnedChunks(size_t count, const std::function<void(size_t, size_t)>& body) {
  const size_t chunks = (count + Gradients::kChunkRays - 1) / Gradients::kChunkRays;
  tbb::parallel_for(size_t{0}, chunks, [&](size_t c) {
    if (!Ranks::world().ownsChunk(c)) return;
    const size_t begin = c * Gradients::kChunkRays;
    body(begin, std::min(count, begin + Gradients::kChunkRays));
  });
}

}  // namespace

size_t adjointRecordBytes() { return sizeof(VertexRecord); }

size_t wavePaths(int maxDepth) {
  const size_t perPath = sizeof(VertexRecord) * static_cast<size_t>(maxDepth + 1);
  return std::clamp<size_t>(kWaveRecordBytes / perPath, 1, kWavefrontWidth);
}

size_t adjointRecordBytesPerThread(int maxDepth) {
  return kRecordedWaves * wavePaths(maxDepth) * static_cast<size_t>(maxDepth + 1) * sizeof(VertexRecord);
}

namespace {
// The estimates of the rays of this rank's chunks (all rays in one process); the others are zero.
std::vector<Color> traceOwnedRays(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                                  const std::vector<BatchRay>& rays, const PathSettings& path,
                                  const std::function<uint64_t(size_t)>& seedOf) {
  std::vector<Color> estimate(rays.size(), Color::Zero());
  forOwnedChunks(rays.size(), [&](size_t begin, size_t end) {
    std::vector<PathSlot> paths;
    NullPathObserver none;
    forEachWave(begin, end, kWavefrontWidth, [&](size_t b, size_t e) {
      paths.clear();
      for (size_t j = b; j < e; ++j) paths.emplace_back(rays[j].origin, rays[j].dir, Pcg32(seedOf(j)));
      tracePaths(scene, lights, scope, path, std::span<PathSlot>(paths),
                 [&](size_t) -> NullPathObserver& { return none; });
      for (size_t j = b; j < e; ++j) estimate[j] = safeRadiance(paths[j - b].L);
    });
  });
  return estimate;
}
}  // namespace

std::vector<Color> traceRays(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                             const std::vector<BatchRay>& rays, const PathSettings& path,
                             const std::function<uint64_t(size_t)>& seedOf) {
  std::vector<Color> estimate = traceOwnedRays(scene, lights, scope, rays, path, seedOf);
  Ranks::world().shareChunks(estimate, Gradients::kChunkRays);
  return estimate;
}

std::vector<Color> primalPass(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                              const std::vector<BatchRay>& rays, const AdjointSettings& settings, uint64_t iteration,
                              std::vector<Color>* albedoSensitivity, bool ownChunksOnly) {
  if (!albedoSensitivity) {
    std::vector<Color> estimate =
        traceOwnedRays(scene, lights, AppearanceScope::uniform(appearance), rays, settings.path,
                       [&](size_t j) { return primalSeed(settings, iteration, j); });
    if (!ownChunksOnly) Ranks::world().shareChunks(estimate, Gradients::kChunkRays);
    return estimate;
  }
  // The same paths, recorded, to read the first vertex's albedo sensitivity off them.
  const AppearanceScope scope = AppearanceScope::uniform(appearance);
  RecordBuffers buffers(settings.path.maxDepth);
  std::vector<Color> estimate(rays.size(), Color::Zero());
  albedoSensitivity->assign(rays.size(), Color::Zero());
  forOwnedChunks(rays.size(), [&](size_t begin, size_t end) {
    RecordedWave wave(appearance, buffers, 0);
    NoScatter none;
    forEachWave(begin, end, buffers.width(), [&](size_t b, size_t e) {
      wave.clear();
      for (size_t j = b; j < e; ++j) wave.add(rays[j].origin, rays[j].dir, primalSeed(settings, iteration, j));
      wave.trace(scene, lights, scope, settings.path);
      for (size_t j = b; j < e; ++j) {
        const AdjointRecorder& rec = wave.path(j - b);
        estimate[j] = safeRadiance(wave.radiance(j - b));
        if ((estimate[j] != 0.0f).any())  // safeRadiance: finite; zero radiance has zero sensitivity
          (*albedoSensitivity)[j] = sweep(rec.records, rec.count, Color::Zero(), settings, none);
      }
    });
  });
  if (!ownChunksOnly) {
    Ranks::world().shareChunks(estimate, Gradients::kChunkRays);
    Ranks::world().shareChunks(*albedoSensitivity, Gradients::kChunkRays);
  }
  return estimate;
}

void adjointPass(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                 const std::vector<BatchRay>& rays, const std::vector<Color>& delta, const AdjointSettings& settings,
                 uint64_t iteration, Gradients& grads, const std::vector<Color>* primalSensitivity) {
  const AppearanceScope scope = AppearanceScope::uniform(appearance);
  RecordBuffers buffers(settings.path.maxDepth);
  const float invN = 1.0f / static_cast<float>(rays.size());
  grads.accumulate(
      rays.size(),
      [&](Gradients::Chunk& chunk, size_t begin, size_t end) {
        Scatterer out(appearance, settings, chunk);
        RecordedWave wave(appearance, buffers, 0);
        std::vector<size_t> traced;  // the wave's rays: those with a nonzero delta
        forEachWave(begin, end, buffers.width(), [&](size_t b, size_t e) {
          wave.clear(), traced.clear();
          for (size_t j = b; j < e; ++j) {
            if ((delta[j] == 0.0f).all()) continue;  // exact: deltas are tiny (1/N), isZero() would drop them
            traced.push_back(j);
            wave.add(rays[j].origin, rays[j].adjointDirection(), adjointSeed(settings, iteration, j));
          }
          wave.trace(scene, lights, scope, settings.path);
          for (size_t i = 0; i < traced.size(); ++i) {
            const size_t j = traced[i];
            const Color& L = wave.radiance(i);
            if (!isFinite(L)) continue;
            const AdjointRecorder& rec = wave.path(i);
            const Color slope = lossResidualSlope(L, rays[j]);
            const Color x = slope * sweep(rec.records, rec.count, delta[j] * slope, settings, out);
            const Color partner = primalSensitivity ? (*primalSensitivity)[j] : x;
            out.albedoCurvature(rec, rayCurvatureWeight(x, partner, rays[j].weight * invN));
          }
        });
      },
      settings.splatVertices());
}

GradientResult computeGradients(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                                const std::vector<BatchRay>& rays, const AdjointSettings& settings, uint64_t iteration,
                                Gradients& grads, std::vector<Color>* estimates) {
  GradientResult result;
  if (estimates) estimates->assign(rays.size(), Color::Zero());
  CHECK(grads.albedo.size() == appearance.albedo.rgb.size());  // the buffers belong to this appearance
  CHECK(grads.albedoCurvature.empty() || grads.albedoCurvature.size() == grads.albedo.size());
  CHECK(settings.path.maxDepth >= 0);
  if (rays.empty()) return result;
  const float invN = 1.0f / static_cast<float>(rays.size());
  auto lossOf = [&](size_t j, const Color& est) { return rays[j].weight * rayLoss(est, rays[j]); };
  auto deltaOf = [&](size_t j, const Color& est) { return rayLossDelta(est, rays[j], rays[j].weight * invN); };
  auto slopeOf = [&](size_t j, const Color& est) { return lossResidualSlope(est, rays[j]); };

  if (settings.pairing == Pairing::Decorrelated) {
    Timer t;
    const bool curvature = !grads.albedoCurvature.empty();
    std::vector<Color> sensitivity;
    // Over MPI ranks a ray's adjoint is traced by the rank that traced its primal: the estimates
    // and sensitivities stay with their rank (core/ranks.h).
    std::vector<Color> estimate =
        primalPass(scene, appearance, lights, rays, settings, iteration, curvature ? &sensitivity : nullptr, true);
    result.times.primal = t.seconds();
    Timer tl;
    std::vector<Color> delta(rays.size());
    std::vector<double> loss(rays.size());
    for (size_t j = 0; j < rays.size(); ++j) {
      loss[j] = lossOf(j, estimate[j]);
      delta[j] = deltaOf(j, estimate[j]);
      if (curvature) sensitivity[j] *= slopeOf(j, estimate[j]);
    }
    result.times.loss = tl.seconds();
    Timer ta;
    adjointPass(scene, appearance, lights, rays, delta, settings, iteration, grads, curvature ? &sensitivity : nullptr);
    Ranks::world().shareChunks(loss, Gradients::kChunkRays);  // another rank's rays' losses, after its adjoint
    result.times.adjoint = ta.seconds();
    double lossSum = 0;
    for (double l : loss) lossSum += l;  // in ray order: the same at any thread or rank count
    result.loss = lossSum * invN;
    if (estimates) {
      Ranks::world().shareChunks(estimate, Gradients::kChunkRays);  // every ray's, for the caller
      *estimates = std::move(estimate);
    }
    return result;
  }

  // crossfit / reuse: one pass that traces with caching and sweeps at once.
  const AppearanceScope scope = AppearanceScope::uniform(appearance);
  const bool crossfit = settings.pairing == Pairing::Crossfit;
  RecordBuffers buffers(settings.path.maxDepth);
  std::vector<double> loss(rays.size(), 0.0);  // summed in ray order: the same at any thread count
  Timer t;
  grads.accumulate(
      rays.size(),
      [&](Gradients::Chunk& chunk, size_t begin, size_t end) {
        Scatterer out(appearance, settings, chunk);
        RecordedWave waveA(appearance, buffers, 0), waveB(appearance, buffers, 1);
        forEachWave(begin, end, buffers.width(), [&](size_t b, size_t e) {
          waveA.clear(), waveB.clear();
          for (size_t j = b; j < e; ++j) {
            waveA.add(rays[j].origin, rays[j].dir, primalSeed(settings, iteration, j));
            if (crossfit) waveB.add(rays[j].origin, rays[j].adjointDirection(), adjointSeed(settings, iteration, j));
          }
          waveA.trace(scene, lights, scope, settings.path);
          if (crossfit) waveB.trace(scene, lights, scope, settings.path);
          for (size_t j = b; j < e; ++j) {
            const AdjointRecorder& recA = waveA.path(j - b);
            const Color a = waveA.radiance(j - b);
            if (!crossfit) {
              if (!isFinite(a)) continue;  // as in the decorrelated pass: no gradient from a broken path
              if (estimates) (*estimates)[j] = a;
              loss[j] = lossOf(j, a);
              const Color x =
                  slopeOf(j, a) * sweep(recA.records, recA.count, deltaOf(j, a) * slopeOf(j, a), settings, out);
              out.albedoCurvature(recA, rayCurvatureWeight(x, x, rays[j].weight * invN));  // biased, as reuse is
              continue;
            }
            const AdjointRecorder& recB = waveB.path(j - b);
            const Color b2 = waveB.radiance(j - b);
            const Color sa = safeRadiance(a), sb = safeRadiance(b2);
            if (estimates) (*estimates)[j] = 0.5f * (sa + sb);
            loss[j] = 0.5 * (lossOf(j, sa) + lossOf(j, sb));
            // Each sample's delta drives the other's path: the derivative of r(a) r(b), a product of
            // independent estimates. A non-finite sample drives nothing and receives nothing.
            if (!isFinite(a) || !isFinite(b2)) continue;
            const Color xb =
                slopeOf(j, b2) * sweep(recB.records, recB.count, 0.5f * deltaOf(j, a) * slopeOf(j, b2), settings, out);
            const Color xa =
                slopeOf(j, a) * sweep(recA.records, recA.count, 0.5f * deltaOf(j, b2) * slopeOf(j, a), settings, out);
            out.albedoCurvature(recA, rayCurvatureWeight(xa, xb, rays[j].weight * invN));
          }
        });
      },
      settings.splatVertices());
  // Written by the rays' own chunks: over MPI ranks, each rank holds its chunks' (core/ranks.h).
  Ranks::world().shareChunks(loss, Gradients::kChunkRays);
  if (estimates) Ranks::world().shareChunks(*estimates, Gradients::kChunkRays);
  result.times.adjoint = t.seconds();
  double lossSum = 0;
  for (double l : loss) lossSum += l;
  result.loss = lossSum * invN;
  return result;
}

}  // namespace relume
