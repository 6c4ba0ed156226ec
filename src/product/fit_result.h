// What a fit writes and reports besides its checkpoints: WORK/result/ (scene.json, albedo
// textures, materials.json, lights.json, frames.json), and the bytes it holds by part.
#pragma once
#include <filesystem>

#include "adjoint/solver.h"
#include "io/json.h"
#include "params/gradients.h"
#include "product/confidence.h"
#include "product/fit_config.h"
#include "product/fit_workspace.h"
#include "product/group_optimiser.h"
#include "product/light_decisions.h"

namespace relume {

struct FitProgress {
  int iterations = 0;
  double loss = 0;              // the last iteration's
  const SamplerStats& sampler;  // summed over the fit
  const Json& peakMemory;       // the largest fitMemory seen
  const Json& budget;           // with time_budget, what it chose (null otherwise)
  const Json& memoryBudget;     // with memory_budget_mib, its plan (MemoryPlan::toJson; null otherwise)
  const Json& convergence;      // with stop_on_convergence, where each albedo stage ended (null otherwise)
};

// Writes WORK/result/ atomically (WORK/result.partial/, then renamed); returns its path.
// frames.json holds `frames` (the frame gains, FrameGains::toJson, and the refined poses);
// albedo_stderr.exr (and a .png preview, white at 0.1) the albedo's standard error per texel when
// `settled` has them: 1, the albedo's whole range, where it is unknown (texels no frame saw, light
// sources' albedo, which is not fitted), 0 off the surface; confidence.{exr,png,json} each texel's
// evidence (product/confidence.h) from prepare's coverage, agreement and median radiance.
std::filesystem::path writeFitResult(const Workspace& w, const Appearance& appearance, const TexelSpace& space,
                                     const ObjectRoles& roles, const FitConfig& c, const Json& frames,
                                     const FitProgress& progress, const SettledAlbedo& settled);

// Bytes of the workspace's mesh arrays (the scene's BVH and face records: Scene::bytes).
double meshBytes(const TriangleMesh& m);
// Bytes a batch holds per ray (the ray, its texel and frame, its object, its colours).
double batchBytesPerRay();
// Bytes of the path records of every thread at path depth `maxDepth`.
double pathRecordBytes(int maxDepth);

// Bytes the fit holds, by part, once a stage's buffers are allocated; "total" leaves out the
// frame cache, a mapping of frames.bin of which only the pages the sampler touches are resident.
Json fitMemory(const Workspace& w, Appearance& appearance, const TexelSpace& space, Gradients& grads,
               const Batch& batch, const AdjointSettings& settings, const GroupOptimiser& optimiser,
               const LightSampler* lights);

}  // namespace relume
