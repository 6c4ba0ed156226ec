// `relume fit WORK`: the reconstruction (Nimier-David et al. 2021, 3.2-3.4) on what `prepare`
// built, in named parts:
//   fit_workspace  what prepare wrote, and the texels of one resolution
//   fit_schedule   the stages: what each fits, at which resolution, for how long
//   fit_batches    each iteration's rays (texture-space sampler, focus sets)
//   adjoint/       the loss gradient (primal then adjoint pass)
//   group_optimiser  masks, the Gauss-Newton albedo step, masked Adam, Polyak averages
//   light_decisions  light sources, out-of-model objects, observed highlights
//   fit_checkpoint   every field of a checkpoint, listed once
// Every choice is a FitConfig key, so the paper's ablation can be rerun. Checkpoints allow
// `--resume` after a kill.
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "adjoint/solver.h"
#include "io/json.h"
#include "product/fit_config.h"

namespace relume {

struct FitSummary {
  double seconds = 0;
  int iterations = 0;
  int finalResolution = 0;
  double finalLoss = 0;
  std::vector<int> emitters;
  std::filesystem::path resultDir;  // empty when stopped
  bool stopped = false;
  Json memory;  // the largest stage's bytes by part
};

// Seconds spent in each phase of an iteration (or summed over several).
struct FitPhaseTimes {
  double sample = 0, lights = 0, primal = 0, loss = 0, adjoint = 0, optimiser = 0;
  double total() const { return sample + lights + primal + loss + adjoint + optimiser; }
  FitPhaseTimes& operator+=(const FitPhaseTimes& o);
  Json toJson() const;
};

// What a caller sees after every iteration (profiling, benchmarks): the batch just used, the
// settings and light sampler it was differentiated with, and the state after the step.
struct FitIteration {
  const std::string& stage;
  int iteration = 0;    // global, 1-based after the step
  double elapsed = 0;   // seconds of fitting so far, time spent in hooks excluded
  FitPhaseTimes times;  // of this iteration
  const std::vector<BatchRay>& rays;
  const std::vector<int>& rayObjects;  // per ray, the object of the surface point it was aimed at
  const Scene& scene;
  const LightSampler& lights;
  const AdjointSettings& settings;  // with this stage's mask
  bool albedoCurvature = false;     // the gradient buffer had Gauss-Newton curvature storage
  const Appearance& appearance;     // albedo on `mesh`'s uv at the stage's resolution
  const TriangleMesh& mesh;
  const Json& memory;       // bytes held by the fit, by part (see memoryBreakdown in fit.cpp), at its largest
  const Json& stageMemory;  // the same in this stage
};

struct FitHooks {
  std::function<bool(const FitIteration&)> afterIteration;  // returns false to stop the fit there
  bool writeFiles = true;  // metrics, checkpoints and the result (off: a measurement leaves WORK as it was)
  // Called once at the end with the final state (Polyak averages applied), files or not.
  std::function<void(const Appearance&, const TriangleMesh&)> finished;
  // The fit's clock in seconds, in place of the steady clock (hook time then counts): tests of the
  // time budget run on a clock they advance themselves.
  std::function<double()> clock;
};

// Runs (or resumes) the fit; writes WORK/result/ (scene.json, albedo.exr/.png, emission
// textures, materials.json), WORK/metrics.jsonl and WORK/checkpoint.bin.
FitSummary runFit(const std::filesystem::path& work, const FitConfig& config, bool resume, const FitHooks& hooks = {});

}  // namespace relume
