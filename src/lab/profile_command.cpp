#include "lab/profile_command.h"

#include <fmt/format.h>

#include <numeric>

#include "capture/transforms.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/json.h"
#include "lab/experiment.h"
#include "lab/profile.h"
#include "scene/atlas.h"
#include "scenes/demo.h"
#include "scenes/synth.h"

namespace relume {
namespace {

void printFitProfile(const ProfileRequest& a) {
  std::filesystem::path work = a.work;
  FitConfig cfg = DemoOptions::demoFitConfig();
  cfg.emissionIterations = 20;  // warm-up only: the profiled stage is what counts
  if (!a.config.empty()) cfg = FitConfig::load(a.config);
  if (a.maxDepthGiven) cfg.maxDepth = a.maxDepth;
  if (work.empty()) work = prepareDemoCapture(a.scratch).work;
  const FitProfile p = profileFit(work, cfg, a.stage, a.iterations);
  const Json j = p.toJson();
  fmt::print("fit iteration  {}: stage {}, {} iterations timed, {} rays/iteration, depth {}, {} threads\n",
             work.string(), p.stage, p.iterations, p.raysPerIteration, p.maxDepth, p.threads);
  fmt::print("  {:<26} {:>9} {:>9} {:>9}\n", "phase (ms)", "mean", "min", "max");
  const std::pair<const char*, const char*> rows[] = {{"sample", "texel sampling + connections"},
                                                      {"lights", "light sampler build"},
                                                      {"primal", "primal"},
                                                      {"loss", "loss"},
                                                      {"adjoint", "adjoint (incl. scatter)"},
                                                      {"optimiser", "optimiser"},
                                                      {"total", "iteration"}};
  for (const auto& [key, label] : rows) {
    const Json& ph = j["phases"][key];
    fmt::print("  {:<26} {:9.2f} {:9.2f} {:9.2f}\n", label, ph["mean_ms"].get<double>(), ph["min_ms"].get<double>(),
               ph["max_ms"].get<double>());
  }
  fmt::print("  whole iteration / primal    {:8.2f}x (means)\n", j["iteration_over_primal"].get<double>());
  const double primalRays = static_cast<double>(p.primalClosestRays + p.primalShadowRays);
  fmt::print("  last batch, replayed (best of 3):\n");
  fmt::print("    connection rays, Embree alone   {:8.2f} ms ({} rays)\n", 1e3 * p.connectionTraceOnly,
             p.raysPerIteration);
  fmt::print("    primal                          {:8.2f} ms  {:.3f} Mpaths/s  {:.2f} Mrays/s ({:.1f} rays/path)\n",
             1e3 * p.primal, p.raysPerIteration / p.primal * 1e-6, primalRays / p.primal * 1e-6,
             primalRays / p.raysPerIteration);
  fmt::print("    primal's rays, Embree alone     {:8.2f} ms  efficiency {:.2f} (trace-only / primal)\n",
             1e3 * p.primalTraceOnly, p.primalTraceOnly / p.primal);
  fmt::print("    adjoint                         {:8.2f} ms  (primal + adjoint) / primal = {:.2f}x\n", 1e3 * p.adjoint,
             (p.primal + p.adjoint) / p.primal);
  fmt::print("    adjoint, no parameter active    {:8.2f} ms  (derivatives + scatter: {:.2f} ms)\n",
             1e3 * p.adjointNoScatter, 1e3 * (p.adjoint - p.adjointNoScatter));
  fmt::print("  per ray {} B between the passes, vertex record {} B x (depth+1) x {} paths per thread ({:.0f} KiB)\n",
             p.rayStateBytes, p.recordBytes, kRecordedWaves * wavePaths(p.maxDepth),
             adjointRecordBytesPerThread(p.maxDepth) / 1024.0);
  fmt::print("  memory held by the fit (MiB):");
  for (const auto& [k, v] : p.memory.items()) fmt::print(" {} {:.1f},", k, v.get<double>() / 1048576.0);
  fmt::print("\n  peak RSS {:.0f} MiB (whole process)\n", p.peakRssMiB);
  if (!a.json.empty()) writeJson(a.json, j);
}

}  // namespace

int runProfileCommand(const ProfileRequest& a) {
  const SynthSceneKind kind = parseSynthScene(a.synth);
  auto wants = [&](const char* w) { return a.what.find(w) != std::string::npos; };
  if (wants("render")) {
    const SceneDescription scene = a.scene.empty() ? makeSynthScene(kind, 1024).scene : loadSceneFile(a.scene);
    const Camera cam = a.scene.empty() ? synthCameraPath(kind, 8, a.width, a.height, 0.0)[2]
                                       : readTransforms(a.cameras).frames.at(0).camera;
    const RenderProfile p = profileRender(scene, cam, a.spp, a.maxDepth, a.raysOut);
    const double rays = static_cast<double>(p.closestRays + p.shadowRays);
    fmt::print("primal render  {}x{} spp {} depth {} threads {} triangles {}\n", p.width, p.height, p.spp, p.maxDepth,
               p.threads, scene.mesh.triangles.size());
    fmt::print(
        "  render       {:8.3f} s  {:7.3f} Mpaths/s  {:6.2f} Mrays/s ({:.1f} rays/path: {} closest, {} shadow)\n",
        p.renderSeconds, p.paths / p.renderSeconds * 1e-6, rays / p.renderSeconds * 1e-6, rays / p.paths, p.closestRays,
        p.shadowRays);
    fmt::print("  trace only   {:8.3f} s  {:6.2f} Mrays/s\n", p.traceOnlySeconds, rays / p.traceOnlySeconds * 1e-6);
    fmt::print("  efficiency   {:8.3f} (trace-only time / render time)\n", p.efficiency());
  }
  if (wants("adjoint") || wants("pairing")) {
    ExperimentOptions eo;
    eo.rays = wants("adjoint") ? a.rays : a.studyRays;
    eo.maxDepth = a.maxDepth;
    eo.atlasResolution = 1024;
    const GradientExperiment e = makeGradientExperiment(kind, eo);
    if (wants("adjoint")) {
      const AdjointProfile p = profileAdjoint(e.truth, e.current, e.rays, a.maxDepth, a.repeats);
      const double iterDirect = p.primal + p.loss + p.adjointDirect, iterFull = p.primal + p.loss + p.adjointFull;
      fmt::print("adjoint iteration  {} rays, depth {}, threads {} (best of {})\n", p.rays, p.maxDepth, p.threads,
                 a.repeats);
      fmt::print("  primal               {:8.3f} s  ({:.3f} Mpaths/s, {:.0f} ns/path)\n", p.primal,
                 p.rays / p.primal * 1e-6, p.primal / p.rays * 1e9);
      fmt::print("  loss                 {:8.4f} s\n", p.loss);
      fmt::print("  adjoint (direct)     {:8.3f} s   iteration/primal = {:.2f}x\n", p.adjointDirect,
                 iterDirect / p.primal);
      fmt::print("  adjoint (full)       {:8.3f} s   iteration/primal = {:.2f}x\n", p.adjointFull, iterFull / p.primal);
      fmt::print("  crossfit (1 pass)    {:8.3f} s   iteration/primal = {:.2f}x\n", p.crossfit, p.crossfit / p.primal);
      fmt::print("  reuse (1 pass)       {:8.3f} s   iteration/primal = {:.2f}x\n", p.reuse, p.reuse / p.primal);
      fmt::print(
          "  Embree alone         {:8.3f} s   primal's {} rays {:.3f} s + adjoint pass's {} rays {:.3f} s; "
          "full iteration = {:.2f}x it\n",
          p.traceOnlyFloor(), p.primalRaysTraced, p.primalTraceOnly, p.adjointRaysTraced, p.adjointTraceOnly,
          iterFull / p.traceOnlyFloor());
      fmt::print("  per-ray state {} B (delta), vertex record {} B x (depth+1) x {} paths per thread ({:.0f} KiB)\n",
                 sizeof(Color), p.recordBytes, kRecordedWaves * wavePaths(p.maxDepth),
                 adjointRecordBytesPerThread(p.maxDepth) / 1024.0);
      fmt::print("  peak RSS {:.0f} MiB (whole process, before the rays were recorded for Embree alone)\n",
                 p.peakRssMiB);
    }
    if (wants("pairing")) {
      const auto stats = studyPairings(e.truth, e.current, e.rays, a.batches, 4 * a.batches);
      fmt::print("pairing study  {} rays x {} batches, reference = {} crossfit batches (unbiased)\n", e.rays.size(),
                 a.batches, 4 * a.batches);
      fmt::print("  {:<13} {:>10} {:>12} {:>12} {:>12}\n", "pairing", "s/iter", "rel bias", "bias (se)",
                 "rel std/iter");
      for (const PairingStat& st : stats)
        fmt::print("  {:<13} {:>10.4f} {:>12.4f} {:>12.2f} {:>12.4f}\n", enumName(st.pairing), st.seconds, st.relBias,
                   st.biasZ, st.relStd);
    }
  }
  if (wants("fit")) printFitProfile(a);
  if (wants("visibility")) {
    const TriangleMesh mesh = buildAtlas(makeScanLikeRoom(1000000, 0.004f), {});
    const Scene scene(mesh);
    for (int res : {1024, 4096}) {
      Timer t;
      const TexelMap m(mesh, res);
      fmt::print("texel map {}^2  {:.2f} s  {:.0f} MiB ({} bytes/texel)\n", res, t.seconds(), m.bytes() / 1048576.0,
                 m.bytes() / m.texelCount());
    }
    const TexelMap map(mesh, 1024);
    fmt::print("visibility index  scan-like room, {} triangles, 1024^2 texels in 32^2 tiles\n", mesh.triangles.size());
    for (int n : {2000, 10000}) {
      std::vector<Frame> frames;
      for (const Camera& c : synthCameraPath(SynthSceneKind::Scan, n, 320, 240, 0.0)) {
        frames.emplace_back();
        frames.back().camera = c;
      }
      std::vector<size_t> use(frames.size());
      std::iota(use.begin(), use.end(), size_t{0});
      Timer t;
      const VisibilityIndex vis = buildVisibilityIndex(scene, map, frames, use, 32, 6);
      fmt::print("  {:>6} frames  {:6.2f} s  {} entries  {:.2f} MB\n", n, t.seconds(), vis.frames.size(),
                 vis.bytes() / 1e6);
    }
  }
  if (wants("leaks")) {
    const SynthScene s = makeSynthScene(SynthSceneKind::Room, 1024);
    const Eigen::AlignedBox3f interior(Vec3(0.05f, 0.05f, 0.05f), Vec3(4.95f, 2.65f, 3.95f));
    fmt::print("edge leaks  random rays from inside the closed room ({} triangles)\n", s.scene.mesh.triangles.size());
    for (const LeakStat& st : studyLeaks(s.scene.mesh, interior, size_t{1} << 24))
      fmt::print("  {:<8} {} rays, {} escaped, {:.2f} Mrays/s\n", st.robust ? "robust" : "default", st.rays, st.misses,
                 st.mraysPerSecond);
  }
  if (wants("scatter")) {
    fmt::print("gradient scatter  random bilinear RGB splats into {}^2, {} threads (time per iteration)\n",
               a.scatterRes, threadCount());
    for (size_t splats : {size_t{1} << 17, size_t{1} << 20, size_t{1} << 24})
      for (const ScatterStat& st : studyScatter(a.scatterRes, splats))
        fmt::print("  {:>9} splats  {:<28} {:8.4f} s  {:7.2f} Msplats/s\n", st.splats, st.strategy, st.seconds,
                   st.splats / st.seconds * 1e-6);
  }
  return 0;
}

}  // namespace relume
