// `relume fit WORK`: the reconstruction (Nimier-David et al. 2021, 3.2-3.4) on what `prepare`
// built. Each iteration draws a batch (texture-space sampler by default), computes the loss
// gradient with the adjoint solver, and takes a masked Adam step per parameter group. Stages
// (defaults): (1) per-object emission from 0, then emitters below a fraction of the total power
// are pruned and frozen; (2) albedo from the median init at the first resolution; (3) + per-object
// roughness and specular, on objects whose highlights the frames observed; (4) the same, coarse to
// fine up to the resolution the frames resolve; (5) emission textures on the emitters only. Every
// choice is a config key, so the paper's ablation can be rerun. Checkpoints allow `--resume`
// after a kill.
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "adjoint/solver.h"
#include "io/json.h"

namespace relume {

struct FitConfig {
  // Sampling
  std::string sampler = "texture";  // texture | image (the ablation's baseline)
  int batchTexels = 8192;           // B: texels per iteration (texture sampler)
  int framesPerTexel = 4;           // K: frames connected per texel
  // While roughness and specular are fitted, this many more texels per iteration drawn from the
  // objects being fitted only: a glossy object is a few percent of the texels and its highlight a
  // few percent of its rays, so its per-object gradient is otherwise too noisy to settle.
  int materialBatchTexels = 2048;
  // And this many from the fitted objects' texels that some frame sees with a light reflected in
  // them: the highlights, where roughness shows.
  int highlightBatchTexels = 0;
  // In the emission stage (with emitter_parameterisation), this many more texels per iteration,
  // shared evenly between the light-source candidates: each object's emission is then weighed
  // against its own pixels, however small it is (fit.cpp, emissionFocus).
  int emissionBatchTexels = 1024;
  // What the rays of those two focused sets are compared with (ray_footprint's values): a
  // highlight a few pixels wide is where the point estimate's blur (bilinear over box-filtered
  // pixels) would pass for a rougher material.
  std::string materialFootprint = "point";
  int imageRays = 16384;            // rays per iteration (image sampler)
  std::string rayFootprint = "point";  // point (the paper's) or pixel: what a ray is compared with (sampling/samplers.h)
  std::string emissionFootprint = "pixel";  // the same for the emission stage's rays (fit.cpp, buildSchedule)
  // Independent (primal, adjoint) pairs per connection. 2 halves the variance of each ray's
  // albedo sensitivity (the indirectly lit ceiling sees the room through 1-spp paths): with
  // albedo_passes 100 and albedo_damping 0.005, the room's albedo MAE 0.033 -> 0.028 (README).
  int samplesPerRay = 2;
  int maxDepth = kDefaultMaxDepth;  // scattering vertices (9 = Cycles' max bounces 8), as synth renders
  std::string gradients = "direct", emitterGradients = "strict", pairing = "decorrelated";
  // Russian roulette after `rouletteDepth` vertices (survival = the path's throughput, clamped to
  // [0.05, 0.95]; unbiased). Room, demo capture, whole default fit (README "Russian roulette"): no
  // roulette 16 rays per path, albedo MAE 0.028; from vertex 5: 9.3 rays, 0.029; from vertex 3: 7
  // rays, 0.031 (the indirectly lit ceiling, whose light is mostly 2+ bounces, gets noisier).
  bool russianRoulette = true;
  int rouletteDepth = 5;            // vertices every path reaches before roulette starts
  // Optimiser
  // Albedo 0.02, not the paper's 0.1: a texel gets a few noisy rays per touch here (the paper's
  // GPU batches gave it many), and masked Adam's sign-like steps then jitter it by ~lr. On the room
  // at 256^2 (100 passes): lr 0.1 -> albedo MAE 0.129, 0.02 -> 0.063, 0.005 -> 0.074 (start 0.115).
  // Roughness and specular 0.02, not the paper's 0.005: the material stage is 150 iterations, and
  // a glossy object's few highlight rays per iteration make the steps smaller than lr. Room demo
  // (table 0.2/0.7, ball 0.1/1.0, from 0.5): 0.005 -> 0.33/0.52 and 0.28/0.68; 0.005 over 450
  // iterations -> 0.20/0.63 and 0.27/0.80; 0.02 -> 0.28/0.66 and 0.035/1.0.
  float lrAlbedo = 0.02f, lrRoughness = 0.02f, lrSpecular = 0.02f;
  // Albedo step: "gauss-newton" (damped diagonal Gauss-Newton, optim/gauss_newton.h) or "adam"
  // (the paper's, at lr_albedo).
  std::string albedoStep = "gauss-newton";
  // Gauss-Newton: fraction of the Newton step taken once a texel has had 1/damping visits (1/visit
  // before), i.e. the estimate averages its last ~1/damping visits. That window sets the albedo's
  // noise: room, default schedule, albedo MAE 0.057 / 0.041 / 0.034 at 0.1 / 0.03 / 0.01 (24
  // frames), 0.063 / 0.044 at 0.1 / 0.03 (96 frames); 0.005 with 100 passes and 2 samples per
  // ray: 0.028 (README).
  float albedoDamping = 0.005f;
  float lrEmission = 0.2f;          // relative: a step is lr * max(E, emissionFloor * brightest observation)
  float emissionFloor = 0.02f;
  // Relative, per texel. Every NEE sample from a lit surface splats onto some emitter texel, so
  // each texel is touched every iteration with a low-SNR gradient and masked Adam jitters it by
  // ~lr per step: at 0.02 the room's mean emission error went 1.5% -> 9.5% in 40 iterations
  // (7.2% -> 11.1% on the 256^2 test capture, 60 iterations); at 0.002 it stays (7.5%) while the
  // held-out PSNR still improves (22.77 -> 23.06 dB).
  float lrEmissionTexture = 0.002f;
  float lrFinalFraction = 0.1f;     // last albedo stage and emission-texture stage: constant lr for
                                    // their first half, then linear down to this
  bool maskedAdam = true, perEntrySteps = true;
  float gradientClamp = 10.0f;      // x the median nonzero gradient magnitude of the group; 0 = off
  float polyakFraction = 0.1f;      // of the final stage; 0 = off
  // The same for the per-object roughness and specular: they are touched every iteration by a few
  // highlight rays, so their last iterates wander by ~lr; averaging the settling stage's second
  // half (with the lr decay) instead of its last 10%: room, whole default fit, glossy ball
  // roughness 0.206 -> 0.165 (truth 0.1), table 0.203 -> 0.183 (0.2), albedo unchanged (README).
  float materialPolyakFraction = 0.5f;
  // Roughness and specular are fitted, with the material texels, through the last albedo stage
  // and settle there; true: they settle (lr decay, average) at the end of the material stage and
  // the finer albedo stages fit the albedo alone, without those texels. 1K room (README "Settling
  // the materials in their stage"): true is 11% faster (18.1 vs 20.3 min) but its albedo MAE is
  // 0.0306-0.0307 against 0.0296-0.0297 and the glossy ball's roughness spreads more by seed.
  bool materialStageSettles = false;
  // Schedule
  int emissionIterations = 200, materialIterations = 300, emissionTextureIterations = 100;
  float albedoPasses = 100.0f;      // albedo stage length: expected draws per sampleable texel
  int maxStageIterations = 2000;    // cap on any albedo stage
  int maxResolution = 0;            // cap on the final albedo resolution; 0 = what the frames resolve
  int emissionTextureResolution = 1024;  // cap on the emission textures' atlas resolution; 0 = the albedo's
  // Light sources (product/light_evidence.h). "reflector": an object is a light when a reflector
  // with albedo <= 1 and the model's specular lobe cannot return its observed radiance, decided
  // after the emission stage and again after the first albedo stage; "radiance_fraction" (the
  // ablation): emission >= emitter_radiance_fraction of its observed radiance, decided once.
  std::string lightTest = "reflector";
  float lightMinUnexplained = 0.5f; // share of its radiance no reflector returns
  float lightSignificance = 3.0f;   // standard errors the unexplained radiance must clear
  float lightMinContrast = 4.0f;    // a light's radiance over the median object's; 0 = off
  int lightEvidenceTexels = 256;    // texels per object drawn for each decision
  bool lightRedecide = true;        // decide again after the first albedo stage
  int emissionRefitIterations = 100;  // emission-only stage after a re-decision that changed the lights
  std::vector<std::string> lights;  // hint: exactly these objects (by name) emit; no decision taken
  // A light source's radiance is all emission (its albedo 0 and not fitted): from any view a
  // Lambertian emission and a diffuse reflection look the same, so the split is a convention, and
  // windows and lamp shades transmit their light rather than reflect it. false: the albedo fitted.
  bool lightAlbedoZero = true;
  float pruneFraction = 0.02f;      // light sources below this fraction of the total power go to 0
  float emitterRadianceFraction = 0.75f;  // light_test radiance_fraction: emission below this fraction
                                          // of the object's observed radiance is lit, not emitting
  // An object's roughness and specular are fitted only where the frames show a highlight: texels
  // seen both with a light in the mirror direction and without, at least `highlightMinPairs` of
  // them, brighter with it by at least `highlightMinContrast` (mean minus two standard errors).
  int highlightMinPairs = 8;
  float highlightMinContrast = 0.1f;
  bool emitterParameterisation = true, medianInit = true, coarseToFine = true, emissionTextures = true;
  float initWhitePoint = 0.8f;      // the median init's 95th-percentile texel becomes this albedo; 0 = off
  uint64_t seed = 1;
  int checkpointEvery = 100, metricsEvery = 10;
  int stopAfterIterations = 0;      // stop (with a checkpoint) after this many iterations; 0 = run to the end

  static FitConfig load(const std::filesystem::path& path);  // unknown key or wrong type: one-line error
  // `base` with the keys `j` gives (the same checks; `where` names the source in errors).
  static FitConfig fromJson(const Json& j, const std::string& where, FitConfig base);
  Json toJson() const;
};

struct FitSummary {
  double seconds = 0;
  int iterations = 0;
  int finalResolution = 0;
  double finalLoss = 0;
  std::vector<int> emitters;
  std::filesystem::path resultDir;   // empty when stopped
  bool stopped = false;
  Json memory;                       // the largest stage's bytes by part
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
  int iteration = 0;          // global, 1-based after the step
  double elapsed = 0;         // seconds of fitting so far, time spent in hooks excluded
  FitPhaseTimes times;        // of this iteration
  const std::vector<BatchRay>& rays;
  const std::vector<int>& rayObjects;  // per ray, the object of the surface point it was aimed at
  const Scene& scene;
  const LightSampler& lights;
  const AdjointSettings& settings;  // with this stage's mask
  bool albedoCurvature = false;     // the gradient buffer had Gauss-Newton curvature storage
  const Appearance& appearance;     // albedo on `mesh`'s uv at the stage's resolution
  const TriangleMesh& mesh;
  const Json& memory;         // bytes held by the fit, by part (see memoryBreakdown in fit.cpp)
};

struct FitHooks {
  std::function<bool(const FitIteration&)> afterIteration;  // returns false to stop the fit there
  bool writeFiles = true;     // metrics, checkpoints and the result (off: a measurement leaves WORK as it was)
  bool report = true;         // with the result, WORK/report/ (re-renders a few frames: tens of seconds)
  // Called once at the end with the final state (Polyak averages applied), files or not.
  std::function<void(const Appearance&, const TriangleMesh&)> finished;
};

// Runs (or resumes) the fit; writes WORK/result/ (scene.json, albedo.exr/.png, emission
// textures, materials.json), WORK/metrics.jsonl and WORK/checkpoint.bin.
FitSummary runFit(const std::filesystem::path& work, const FitConfig& config, bool resume, const FitHooks& hooks = {});

}  // namespace relume
