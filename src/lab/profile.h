// Measured cost of the renderer and (later) of an optimisation iteration, by phase.
#pragma once
#include "adjoint/solver.h"
#include "product/fit.h"
#include "scenes/synth.h"
#include "render/path_tracer.h"

namespace relume {

struct RenderProfile {
  int width = 0, height = 0, spp = 0, maxDepth = 0, threads = 0;
  double renderSeconds = 0, traceOnlySeconds = 0;
  uint64_t paths = 0, closestRays = 0, shadowRays = 0;
  double efficiency() const { return traceOnlySeconds / renderSeconds; }
};

// Renders one view, then replays exactly the same rays through Embree alone. With raysOut, also
// writes those rays there (little-endian float32 records: origin xyz, direction xyz, tmax (inf for
// a closest hit), 1 for a shadow ray / 0) so that another tracer can replay them.
RenderProfile profileRender(const SceneDescription& scene, const Camera& camera, int spp, int maxDepth,
                            const std::filesystem::path& raysOut = {});

}  // namespace relume

namespace relume {

struct AdjointProfile {
  size_t rays = 0;
  int maxDepth = 0, threads = 0;
  double primal = 0, loss = 0, adjointDirect = 0, adjointFull = 0, crossfit = 0, reuse = 0;
  // Embree alone on the rays the primal and the adjoint pass trace (decorrelated, iteration 0):
  // what an iteration would cost if everything but the traversal were free.
  double primalTraceOnly = 0, adjointTraceOnly = 0;
  size_t primalRaysTraced = 0, adjointRaysTraced = 0;
  size_t recordBytes = 0;
  double peakRssMiB = 0;  // after the timed passes, before the rays are recorded for the replay
  double traceOnlyFloor() const { return primalTraceOnly + adjointTraceOnly; }
};
// Times each pass of one iteration on a batch (best of `repeats`), and Embree alone on its rays.
AdjointProfile profileAdjoint(const SceneDescription& scene, const Appearance& current,
                              const std::vector<BatchRay>& rays, int maxDepth, int repeats);

struct PairingStat {
  Pairing pairing;
  double seconds = 0;  // per iteration
  double relBias = 0;  // |mean - reference| / |reference|, RMS over parameters
  double relStd = 0;   // per-iteration std / |reference|, RMS over parameters
  double biasZ = 0;    // |mean - reference| in standard errors, RMS over parameters (~1 if unbiased)
};
// Bias and variance of each pairing's gradient against a high-sample reference (mean of many
// crossfit batches, which is unbiased), over the per-object parameters.
std::vector<PairingStat> studyPairings(const SceneDescription& scene, const Appearance& current,
                                       const std::vector<BatchRay>& rays, int batches, int referenceBatches);

struct ScatterStat {
  const char* strategy;
  size_t splats;
  double seconds;  // including zeroing/reduction, i.e. per iteration
};
// Random bilinear RGB splats into a resolution^2 texture from all threads: atomics, per-thread
// buffers + reduction (the reduction is part of every iteration's cost), and the chunk logs the
// gradient buffers use (thread-count independent sums).
std::vector<ScatterStat> studyScatter(int resolution, size_t splats);

}  // namespace relume

namespace relume {
struct LeakStat {
  bool robust;
  size_t rays, misses;
  double mraysPerSecond;
};
// Random rays from inside a closed scene's bounding box interior: every miss is a leak through a
// shared edge. Compares Embree's default and robust intersection.
std::vector<LeakStat> studyLeaks(const TriangleMesh& closedMesh, const Eigen::AlignedBox3f& interior, size_t rays);
}  // namespace relume

namespace relume {

// Cost of real fit iterations, by phase. The fit runs from its start (nothing written to WORK);
// iterations before the first stage whose name starts with `stage` are warm-up, then
// `iterations` are timed and the fit stops. On the last one, splits the timers cannot see are
// measured by replaying its batch: the connection rays and the primal's rays through Embree alone
// (efficiency), and the adjoint pass without any active parameter (what derivatives + scatter cost).
struct FitProfile {
  std::string stage;
  int iterations = 0, threads = 0, maxDepth = 0;
  size_t raysPerIteration = 0;  // training rays (connections) of the last batch
  std::vector<FitPhaseTimes> perIteration;
  double connectionTraceOnly = 0;          // the batch's camera rays, Embree alone
  double primal = 0, primalTraceOnly = 0;  // best of 3 on the last batch
  uint64_t primalClosestRays = 0, primalShadowRays = 0;
  double adjoint = 0, adjointNoScatter = 0;  // best of 3: the stage's parameters, and none
  size_t recordBytes = 0, rayStateBytes = 0;
  double peakRssMiB = 0;
  Json memory;
  Json toJson() const;
};

FitProfile profileFit(const std::filesystem::path& work, const FitConfig& config, const std::string& stage,
                      int iterations);

}  // namespace relume
