#include "lab/profile.h"

#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <fstream>
#include <numeric>

#include "core/error.h"
#include "core/system.h"
#include "core/warp.h"
#include "io/atomic_file.h"
#include "render/film.h"
#include "core/random_streams.h"

namespace relume {
namespace {

struct RecordedRay {
  Vec3 origin, dir;
  float tmax;
  bool shadow;
};

struct RayRecorder : NullPathObserver {
  std::vector<RecordedRay>* out;
  void traced(const Vec3& o, const Vec3& d, float tmax, bool shadow) { out->push_back({o, d, tmax, shadow}); }
};

struct PathStart {
  Vec3 origin, dir;
  Pcg32 rng;
};

// Every ray that paths 0..count-1 trace (closest hits and shadow rays), path j started by
// `start(j)` with the seed the measured pass used, so the replay traces exactly its rays.
std::vector<RecordedRay> recordPathRays(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                                        const PathSettings& path, size_t count,
                                        const std::function<std::optional<PathStart>(size_t)>& start) {
  tbb::enumerable_thread_specific<std::vector<RecordedRay>> recorded;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 256), [&](const tbb::blocked_range<size_t>& range) {
    RayRecorder rec;
    rec.out = &recorded.local();
    std::vector<PathSlot> wave;
    forEachWave(range.begin(), range.end(), kWavefrontWidth, [&](size_t b, size_t e) {  // as the passes trace them
      wave.clear();
      for (size_t j = b; j < e; ++j)
        if (auto s = start(j)) wave.emplace_back(s->origin, s->dir, s->rng);
      tracePaths(scene, lights, scope, path, std::span<PathSlot>(wave), [&](size_t) -> RayRecorder& { return rec; });
    });
  });
  std::vector<RecordedRay> rays;
  for (auto& v : recorded) rays.insert(rays.end(), v.begin(), v.end());
  return rays;
}

// The rays one pass of computeGradients traces on `rays` at `iteration`: the primal's, or the
// adjoint pass's (its seeds and directions).
std::vector<RecordedRay> gradientPassRays(const Scene& scene, const LightSampler& lights, const Appearance& appearance,
                                          const AdjointSettings& s, const std::vector<BatchRay>& rays,
                                          uint64_t iteration, bool adjointPass) {
  return recordPathRays(scene, lights, AppearanceScope::uniform(appearance), s.path, rays.size(), [&](size_t j) {
    const BatchRay& ray = rays[j];
    return std::optional<PathStart>({ray.origin, adjointPass ? ray.adjointDirection() : ray.dir,
                                     Pcg32(adjointPass ? adjointSeed(s, iteration, j) : primalSeed(s, iteration, j))});
  });
}

// Embree alone on the recorded rays, best of `repeats`.
double traceOnlySeconds(const Scene& scene, const std::vector<RecordedRay>& rays, int repeats) {
  double best = INFINITY;
  for (int rep = 0; rep < repeats; ++rep) {
    Timer t;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 4096), [&](const tbb::blocked_range<size_t>& range) {
      size_t hits = 0;
      for (size_t i = range.begin(); i < range.end(); ++i) {
        const RecordedRay& ray = rays[i];
        if (ray.shadow)
          hits += scene.occluded(ray.origin, ray.dir, ray.tmax);
        else
          hits += std::isfinite(scene.hitDistance(ray.origin, ray.dir, ray.tmax));
      }
      volatile size_t sink = hits;  // keep the traversal from being optimised away
      (void)sink;
    });
    best = std::min(best, t.seconds());
  }
  return best;
}

void writeRays(const std::filesystem::path& path, const std::vector<RecordedRay>& rays) {
  std::vector<float> records;
  records.reserve(rays.size() * 8);
  for (const RecordedRay& r : rays)
    records.insert(records.end(), {r.origin.x(), r.origin.y(), r.origin.z(), r.dir.x(), r.dir.y(), r.dir.z(), r.tmax,
                                   r.shadow ? 1.0f : 0.0f});
  writeAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f.write(reinterpret_cast<const char*>(records.data()),
            static_cast<std::streamsize>(records.size() * sizeof(float)));
    if (!f.flush()) fail("cannot write {}", path.string());
  });
}

}  // namespace

RenderProfile profileRender(const SceneDescription& desc, const Camera& camera, int spp, int maxDepth,
                            const std::filesystem::path& raysOut) {
  Scene scene(desc.mesh);
  LightSampler lights(scene, desc.appearance);
  RenderOptions ro;
  ro.spp = spp;
  ro.path.maxDepth = maxDepth;
  renderImage(scene, desc.appearance, lights, camera, ro);  // warm-up (page faults, BVH in cache)
  // Best of 5: this VM's timings vary by tens of percent between runs.
  RenderResult r = renderImage(scene, desc.appearance, lights, camera, ro);
  for (int rep = 1; rep < 5; ++rep) {
    RenderResult again = renderImage(scene, desc.appearance, lights, camera, ro);
    if (again.stats.seconds < r.stats.seconds) r = std::move(again);
  }
  // Record the same paths' rays (same seeds), then time Embree alone on them.
  const size_t pixels = static_cast<size_t>(camera.width) * camera.height;
  const std::vector<RecordedRay> rays =
      recordPathRays(scene, lights, AppearanceScope::uniform(desc.appearance), ro.path, pixels * spp, [&](size_t j) {
        const int x = static_cast<int>(j / spp % camera.width), y = static_cast<int>(j / spp / camera.width);
        CameraSample cs = cameraSample(camera, x, y, static_cast<int>(j % spp), ro.seed);
        return cs.dir ? std::optional<PathStart>({camera.position, *cs.dir, cs.rng}) : std::nullopt;
      });
  RenderProfile p;
  p.width = camera.width, p.height = camera.height, p.spp = spp, p.maxDepth = maxDepth, p.threads = threadCount();
  p.renderSeconds = r.stats.seconds;
  p.paths = r.stats.paths;
  for (const RecordedRay& ray : rays) (ray.shadow ? p.shadowRays : p.closestRays)++;
  p.traceOnlySeconds = traceOnlySeconds(scene, rays, 5);
  if (!raysOut.empty()) writeRays(raysOut, rays);
  return p;
}

}  // namespace relume

namespace relume {

AdjointProfile profileAdjoint(const SceneDescription& desc, const Appearance& current,
                              const std::vector<BatchRay>& rays, int maxDepth, int repeats) {
  Scene scene(desc.mesh);
  const LightSampler lights(scene, current);
  AdjointProfile p;
  p.rays = rays.size();
  p.maxDepth = maxDepth;
  p.threads = threadCount();
  p.recordBytes = adjointRecordBytes();
  AdjointSettings s;
  s.path.maxDepth = maxDepth;
  Gradients g(current);
  auto best = [](double& slot, double v) { slot = slot == 0 ? v : std::min(slot, v); };
  for (int r = 0; r < repeats; ++r) {
    s.mode = GradientMode::Direct;
    s.pairing = Pairing::Decorrelated;
    g.clear();
    const GradientResult direct = computeGradients(scene, current, lights, rays, s, r, g);
    best(p.primal, direct.times.primal);
    best(p.loss, direct.times.loss);
    best(p.adjointDirect, direct.times.adjoint);
    s.mode = GradientMode::Full;
    g.clear();
    best(p.adjointFull, computeGradients(scene, current, lights, rays, s, r, g).times.adjoint);
    s.mode = GradientMode::Direct;
    for (Pairing pairing : {Pairing::Crossfit, Pairing::Reuse}) {
      s.pairing = pairing;
      g.clear();
      best(pairing == Pairing::Crossfit ? p.crossfit : p.reuse,
           computeGradients(scene, current, lights, rays, s, r, g).times.adjoint);
    }
  }
  p.peakRssMiB = peakRssMiB();
  s.pairing = Pairing::Decorrelated;
  const std::vector<RecordedRay> primalRays = gradientPassRays(scene, lights, current, s, rays, 0, false),
                                 adjointRays = gradientPassRays(scene, lights, current, s, rays, 0, true);
  p.primalRaysTraced = primalRays.size();
  p.adjointRaysTraced = adjointRays.size();
  p.primalTraceOnly = traceOnlySeconds(scene, primalRays, repeats);
  p.adjointTraceOnly = traceOnlySeconds(scene, adjointRays, repeats);
  return p;
}

std::vector<PairingStat> studyPairings(const SceneDescription& desc, const Appearance& current,
                                       const std::vector<BatchRay>& rays, int batches, int referenceBatches) {
  Scene scene(desc.mesh);
  const LightSampler lights(scene, current);
  std::vector<ParamRef> params;
  for (int o = 0; o < current.objectCount(); ++o) {
    params.push_back({ParamKind::Roughness, o});
    params.push_back({ParamKind::Specular, o});
    if (current.isEmissive(o)) params.push_back({ParamKind::Emission, o, 0, 1});
  }
  auto run = [&](Pairing pairing, int n, uint64_t firstIteration, std::vector<std::vector<double>>* samples) {
    AdjointSettings s;
    s.pairing = pairing;
    Gradients g(current);
    Timer t;
    std::vector<double> mean(params.size(), 0.0);
    for (int b = 0; b < n; ++b) {
      g.clear();
      computeGradients(scene, current, lights, rays, s, firstIteration + b, g);
      for (size_t i = 0; i < params.size(); ++i) {
        mean[i] += gradientValue(current, g, params[i]) / n;
        if (samples) (*samples)[i].push_back(gradientValue(current, g, params[i]));
      }
    }
    return std::pair{mean, t.seconds() / n};
  };
  std::vector<std::vector<double>> refSamples(params.size());
  const auto [reference, refTime] = run(Pairing::Crossfit, referenceBatches, 1'000'000, &refSamples);
  std::vector<PairingStat> out;
  for (Pairing pairing : {Pairing::Decorrelated, Pairing::Crossfit, Pairing::Reuse}) {
    std::vector<std::vector<double>> samples(params.size());
    const auto [mean, seconds] = run(pairing, batches, 0, &samples);
    PairingStat st{pairing, seconds};
    int counted = 0;
    for (size_t i = 0; i < params.size(); ++i) {
      const double ref = std::abs(reference[i]);
      if (ref < 1e-12) continue;
      double var = 0;
      for (double v : samples[i]) var += (v - mean[i]) * (v - mean[i]);
      var /= std::max(1, batches - 1);
      double refVar = 0;
      for (double v : refSamples[i]) refVar += (v - reference[i]) * (v - reference[i]);
      refVar /= std::max(1, referenceBatches - 1);
      st.biasZ += sqr(mean[i] - reference[i]) / (var / batches + refVar / referenceBatches + 1e-300);
      st.relBias += sqr((mean[i] - reference[i]) / ref);
      st.relStd += var / (ref * ref);
      ++counted;
    }
    st.relBias = std::sqrt(st.relBias / std::max(1, counted));
    st.relStd = std::sqrt(st.relStd / std::max(1, counted));
    st.biasZ = std::sqrt(st.biasZ / std::max(1, counted));
    out.push_back(st);
  }
  return out;
}

std::vector<ScatterStat> studyScatter(int resolution, size_t splats) {
  Texture tex(resolution, resolution);
  std::vector<float> target(tex.rgb.size(), 0.0f);
  auto footprintOf = [&](size_t i) {
    Pcg32 rng(i);
    return tex.footprint(rng.next2D());
  };
  std::vector<ScatterStat> out;
  {
    Timer t;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, splats, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const TexelFootprint fp = footprintOf(i);
        for (int k = 0; k < 4; ++k)
          for (int c = 0; c < 3; ++c)
            std::atomic_ref<float>(target[3 * fp.index[k] + c]).fetch_add(fp.weight[k], std::memory_order_relaxed);
      }
    });
    out.push_back({"atomic_ref<float>", splats, t.seconds()});
  }
  {
    Timer t;
    tbb::enumerable_thread_specific<std::vector<float>> local([&] { return std::vector<float>(target.size(), 0.0f); });
    tbb::parallel_for(tbb::blocked_range<size_t>(0, splats, 4096), [&](const tbb::blocked_range<size_t>& r) {
      std::vector<float>& buf = local.local();
      for (size_t i = r.begin(); i < r.end(); ++i) {
        const TexelFootprint fp = footprintOf(i);
        for (int k = 0; k < 4; ++k)
          for (int c = 0; c < 3; ++c) buf[3 * fp.index[k] + c] += fp.weight[k];
      }
    });
    tbb::parallel_for(tbb::blocked_range<size_t>(0, target.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
      for (const std::vector<float>& buf : local)
        for (size_t i = r.begin(); i < r.end(); ++i) target[i] += buf[i];
    });
    out.push_back({"per-thread + reduce", splats, t.seconds()});
  }
  {
    Appearance shape(1);
    shape.albedo = tex;
    Gradients grads(shape);
    Timer t;
    grads.accumulate(splats, [&](Gradients::Chunk& chunk, size_t begin, size_t end) {
      for (size_t i = begin; i < end; ++i) {
        const TexelFootprint fp = footprintOf(i);
        for (int k = 0; k < 4; ++k) chunk.addAlbedo(fp.index[k], Color::Constant(fp.weight[k]));
      }
    });
    out.push_back({"chunk logs, ray order (used)", splats, t.seconds()});
  }
  return out;
}

}  // namespace relume

namespace relume {

std::vector<LeakStat> studyLeaks(const TriangleMesh& mesh, const Eigen::AlignedBox3f& interior, size_t rays) {
  std::vector<LeakStat> out;
  for (bool robust : {false, true}) {
    SceneOptions so;
    so.robust = robust;
    const Scene scene(mesh, so);
    tbb::combinable<size_t> misses([] { return size_t{0}; });
    Timer t;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays, 8192), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i < r.end(); ++i) {
        Pcg32 rng(hashTuple({i, streamTag(RandomStream::LeakRays)}));
        const Vec3 o = interior.min() + interior.sizes().cwiseProduct(rng.next3D());
        misses.local() += !std::isfinite(scene.hitDistance(o, squareToUniformSphere(rng.next2D())));
      }
    });
    out.push_back({robust, rays, misses.combine(std::plus<>()), rays / t.seconds() * 1e-6});
  }
  return out;
}

}  // namespace relume

namespace relume {

FitProfile profileFit(const std::filesystem::path& work, const FitConfig& config, const std::string& stage,
                      int iterations) {
  FitProfile p;
  p.threads = threadCount();
  p.maxDepth = config.maxDepth;
  FitHooks hooks;
  hooks.writeFiles = false;
  hooks.afterIteration = [&](const FitIteration& it) {
    if (it.stage.rfind(stage, 0) != 0) return p.perIteration.empty();  // warm-up; stop once the stage is over
    p.stage = it.stage;
    p.perIteration.push_back(it.times);
    if (static_cast<int>(p.perIteration.size()) < iterations) return true;
    // The last batch, replayed (at the iteration it was drawn in, i.e. with its seeds).
    const uint64_t iteration = static_cast<uint64_t>(it.iteration - 1);
    p.raysPerIteration = it.rays.size();
    std::vector<RecordedRay> connections;
    for (const BatchRay& r : it.rays) connections.push_back({r.origin, r.dir, INFINITY, false});
    p.connectionTraceOnly = traceOnlySeconds(it.scene, connections, 3);
    const std::vector<RecordedRay> primalRays =
        gradientPassRays(it.scene, it.lights, it.appearance, it.settings, it.rays, iteration, false);
    for (const RecordedRay& r : primalRays) (r.shadow ? p.primalShadowRays : p.primalClosestRays)++;
    p.primalTraceOnly = traceOnlySeconds(it.scene, primalRays, 3);
    AdjointSettings none = it.settings;
    none.mask = ParamMask::only({});
    Gradients grads(it.appearance, it.albedoCurvature);  // as the fit: paths recorded in the primal
    auto best = [](double& slot, double v) { slot = slot == 0 ? v : std::min(slot, v); };
    for (int rep = 0; rep < 3; ++rep) {
      grads.clear();
      const GradientResult g =
          computeGradients(it.scene, it.appearance, it.lights, it.rays, it.settings, iteration, grads);
      best(p.primal, g.times.primal);
      best(p.adjoint, g.times.adjoint);
      grads.clear();
      best(p.adjointNoScatter,
           computeGradients(it.scene, it.appearance, it.lights, it.rays, none, iteration, grads).times.adjoint);
    }
    p.memory = it.memory;
    return false;
  };
  runFit(work, config, false, hooks);
  if (p.perIteration.empty()) fail("profile: the fit has no stage named {}*", stage);
  p.iterations = static_cast<int>(p.perIteration.size());
  p.recordBytes = adjointRecordBytes();
  p.rayStateBytes = sizeof(BatchRay) + sizeof(Color);  // the ray, and its delta between the passes
  p.peakRssMiB = peakRssMiB();
  return p;
}

Json FitProfile::toJson() const {
  std::vector<Json> rows;  // each iteration's phases, and their total
  for (const FitPhaseTimes& t : perIteration) {
    rows.push_back(t.toJson());
    rows.back()["total"] = t.total();
  }
  Json phases = Json::object();
  for (const auto& [name, unused] : rows.front().items()) {
    std::vector<double> v;
    for (const Json& r : rows) v.push_back(r[name].get<double>());
    phases[name] = {{"mean_ms", 1e3 * std::accumulate(v.begin(), v.end(), 0.0) / v.size()},
                    {"min_ms", 1e3 * *std::min_element(v.begin(), v.end())},
                    {"max_ms", 1e3 * *std::max_element(v.begin(), v.end())}};
  }
  return {
      {"stage", stage},
      {"iterations", iterations},
      {"threads", threads},
      {"max_depth", maxDepth},
      {"rays_per_iteration", raysPerIteration},
      {"phases", phases},
      {"iteration_over_primal", phases["total"]["mean_ms"].get<double>() / phases["primal"]["mean_ms"].get<double>()},
      {"connection_trace_only_ms", 1e3 * connectionTraceOnly},
      {"primal_ms", 1e3 * primal},
      {"primal_trace_only_ms", 1e3 * primalTraceOnly},
      {"primal_closest_rays", primalClosestRays},
      {"primal_shadow_rays", primalShadowRays},
      {"adjoint_ms", 1e3 * adjoint},
      {"adjoint_no_scatter_ms", 1e3 * adjointNoScatter},
      {"record_bytes", recordBytes},
      {"ray_state_bytes", rayStateBytes},
      {"peak_rss_mib", peakRssMiB},
      {"memory_bytes", memory}};
}

}  // namespace relume
