#include "product/fit.h"

#include <spdlog/spdlog.h>

#include <fstream>
#include <iterator>
#include <optional>

#include "core/check.h"
#include "core/error.h"
#include "core/random_streams.h"
#include "core/ranks.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "optim/albedo_convergence.h"
#include "optim/checkpoint.h"
#include "optim/texel_smoothing.h"
#include "optim/upsample.h"
#include "product/fit_batches.h"
#include "product/fit_checkpoint.h"
#include "product/fit_result.h"
#include "product/fit_schedule.h"
#include "product/fit_workspace.h"
#include "product/frame_gains.h"
#include "product/frame_poses.h"
#include "product/group_optimiser.h"
#include "product/light_decisions.h"
#include "product/memory_budget.h"
#include "product/time_budget.h"

namespace relume {
namespace fs = std::filesystem;
namespace {

constexpr const char* kMemoryResolutionKey = "memory_budget.resolution";  // the plan's, in the checkpoint

// One fit: the stages of the schedule, each a loop of iterations
//   batch (FitBatches) -> gradient (adjoint solver) -> masks and step (GroupOptimiser),
// with the light decisions at stage boundaries and checkpoints along the way.
class Fit {
 public:
  Fit(const fs::path& work, const FitConfig& config, const FitHooks& hooks)
      : c_(config),
        hooks_(hooks),
        clockStart_(hooks.clock ? hooks.clock() : 0.0),
        w_(work),
        appearance_(w_.mesh.objectCount),
        roles_(appearance_.objectCount()),
        batches_(c_, w_),
        optimiser_(c_),
        gains_(resolveFrameGains(c_.frameGains, w_.frames, *w_.store, w_.kept), w_.frames.size(), w_.kept,
               c_.gainReferenceFrame, c_.gainMemory),
        decisions_(c_, w_, appearance_, roles_, settings_.path, gains_),
        poses_(w_.frames),
        refinePoses_(c_.refinePoses == RefinePoses::On || (c_.refinePoses == RefinePoses::Auto && !w_.exactPoses)) {
    settings_.mode = c_.gradients;
    settings_.emitters = c_.emitterGradients;
    settings_.pairing = c_.pairing;
    settings_.path.maxDepth = c_.maxDepth;
    settings_.path.russianRoulette = c_.russianRoulette;
    settings_.path.rouletteDepth = c_.rouletteDepth;
    settings_.seed = c_.seed;
    for (const auto& [id, name] : w_.names)
      if (id >= 0 && id < appearance_.objectCount()) appearance_.names[id] = name;
    std::fill(appearance_.albedoFromTexture.begin(), appearance_.albedoFromTexture.end(), 1);
  }

  FitSummary run(bool resume);

 private:
  void checkRanksAgree(uintmax_t checkpointBytes) const;
  std::vector<int> chooseResolutions(const TexelSpace& init);
  std::vector<int> keepMemoryBudget(std::vector<int> resolutions, const TexelSpace& init, const Checkpoint* resumed);
  std::unique_ptr<TexelSpace> start(const Stage& first);
  std::unique_ptr<TexelSpace> resume(const Checkpoint& ck, size_t stageCount, FitPosition& at);
  void initialiseAlbedo(const TexelSpace& space);
  std::vector<float> medianRadiance(const TexelSpace& space) const;
  void settleAlbedoError();
  // Per texel of `space`, whether its albedo is fitted: updatable, on the frames, not held by a light.
  std::vector<uint8_t> fittedAlbedoTexels(const TexelSpace& space) const;
  void smoothAlbedo(const TexelSpace& space);
  void upsampleAlbedo(const TexelSpace& from, const TexelSpace& to);
  bool skips(const Stage& st) const;
  void runStage(size_t stageIndex, int firstIteration, const TexelSpace& space);
  void iterate(size_t stageIndex, int firstIteration, const TexelSpace& space);
  void planBudget(size_t stageIndex, int done);
  // Iterations per pass over `space`'s sampleable texels (as the schedule counts albedo passes).
  double iterationsPerPass(const TexelSpace& space) const {
    const int drawn = c_.sampler == SamplerKind::Texture ? c_.batchTexels : c_.imageRays;
    return static_cast<double>(space.sampleable.size()) / std::max(1, drawn);
  }
  int convergenceCheckEvery(const TexelSpace& space) const {
    return std::max(1, static_cast<int>(std::ceil(c_.convergenceCheckPasses * iterationsPerPass(space))));
  }
  void startConvergence(size_t stageIndex, const TexelSpace& space);
  void checkConvergence(size_t stageIndex, int done, const TexelSpace& space, Progress& progress);
  void finishStage(const Stage& st, size_t stageIndex, const TexelSpace& space);
  void refinePoses(const std::string& after);

  // Emission textures cover each emitter's uv window; an emitter with a large window (a window, a
  // wall wrongly kept as a light) would otherwise hold a 4096^2-scale texture with its optimiser
  // state, gradient and average.
  int emissionTextureResolution(int albedoResolution) const {
    return c_.emissionTextureResolution > 0 ? std::min(albedoResolution, c_.emissionTextureResolution)
                                            : albedoResolution;
  }
  // Seconds of fitting: this run's, time spent in hooks left out, and those of the run it resumed.
  double fitSeconds() const {
    return elapsedBefore_ + (hooks_.clock ? hooks_.clock() - clockStart_ : total_.seconds() - hookSeconds_);
  }
  // fitSeconds() as the root rank measured it, for the time budget's decisions: every rank then
  // plans the same stage lengths (core/ranks.h). Collective over MPI ranks.
  double agreedFitSeconds() const { return Ranks::world().rootValue(fitSeconds()); }
  Json memoryBreakdown(Gradients& grads, const Batch& batch, const AdjointSettings& settings, const TexelSpace& space) {
    return fitMemory(w_, appearance_, space, grads, batch, settings, optimiser_, lights_ ? &*lights_ : nullptr);
  }
  // With time_budget: the budget, the stage lengths it chose, its last plan and the time taken.
  Json budgetSummary() const;
  // With stop_on_convergence: the threshold, and each albedo stage's length, where it converged
  // (0: it ran all its passes) and the most it could have run.
  Json convergenceSummary() const;
  void appendMetrics(const Json& j) const;
  void serialiseState(CheckpointIo& io);
  void serialiseConvergence(CheckpointIo& io);
  void writeCheckpoint(size_t stage, int iteration, const TexelSpace& space);
  fs::path writeResult(const TexelSpace& space) const {
    Json frames = gains_.toJson(w_.frames);
    if (poses_.refined()) frames["poses"] = poses_.toJson(w_.frames);
    return writeFitResult(w_, appearance_, space, roles_, c_, frames,
                          {globalIteration_, lastLoss_, stats_, peakMemory_, budgetSummary(),
                           memoryPlan_ ? memoryPlan_->toJson() : Json(), convergenceSummary()},
                          settled_);
  }

  FitConfig c_;
  FitHooks hooks_;
  Timer total_;
  double hookSeconds_ = 0;
  double clockStart_ = 0;     // hooks_.clock() when the fit started
  double elapsedBefore_ = 0;  // fit seconds of the runs this one resumes
  std::vector<Stage> stages_;
  std::optional<TimeBudget> budget_;  // with time_budget
  std::optional<MemoryPlan> memoryPlan_;  // with memory_budget_mib
  Json lastPlan_;                     // the budget's last plan
  double lastIterationEnd_ = 0;       // fitSeconds() then (the setup, then each iteration's end)
  Json peakMemory_;
  Workspace w_;
  Appearance appearance_;
  AdjointSettings settings_;
  ObjectRoles roles_;
  FitBatches batches_;
  GroupOptimiser optimiser_;
  FrameGains gains_;
  LightDecisions decisions_;
  FramePoses poses_;
  bool refinePoses_;
  SamplerStats stats_;
  SettledAlbedo settled_;               // the settled albedo's standard errors and unbounded values
  std::optional<LightSampler> lights_;  // by the current emission; each iteration's shares the last's tables
  // With stop_on_convergence: how far the albedo of the stage that runs (convergenceStage_) moved.
  std::optional<AlbedoConvergence> convergence_;
  int convergenceStage_ = -1;
  size_t lightSamplerBytesPeak_ = 0;    // the most lights_->bytes() has been
  float radianceScale_ = 1e-6f;
  int finalRes_ = 0;
  int globalIteration_ = 0;
  bool stopped_ = false;
  double lastLoss_ = 0;
};

// The prepared resolutions up to what the frames resolve (or max_resolution); also the radiance
// scale of emission steps, from a probe batch (lights are what is brightest).
std::vector<int> Fit::chooseResolutions(const TexelSpace& init) {
  {
    TextureSpaceSampler probe(*w_.scene, init.map, init.sampleable, w_.vis, w_.trainingFrames());
    const Batch b =
        probe.sample(c_.seed, 0xFFFFFFFF, {std::min(c_.batchTexels, 4096), c_.framesPerTexel, c_.rayFootprint});
    finalRes_ = c_.maxResolution > 0 ? c_.maxResolution : w_.resolvedResolution(b);
    if (b.rays.empty()) fail("{}: no frame connection survived (every texel occluded or off-frame?)", w_.dir.string());
    for (const BatchRay& r : b.rays)
      if (std::isfinite(r.reference.maxCoeff())) radianceScale_ = std::max(radianceScale_, r.reference.maxCoeff());
    optimiser_.setRadianceScale(radianceScale_);
  }
  std::vector<int> resolutions;
  for (int r : w_.resolutions)
    if (r <= finalRes_) resolutions.push_back(r);
  if (resolutions.empty()) fail("fit: max_resolution {} is below the init resolution {}", finalRes_, w_.initResolution);
  if (!c_.coarseToFine) resolutions = {resolutions.back()};
  finalRes_ = resolutions.back();
  return resolutions;
}

// With memory_budget_mib: the resolutions up to the finest whose predicted peak fits
// (product/memory_budget.h); refuses the fit when not even the coarsest does. A resumed fit keeps
// the resolution of the run it continues (`resumed`'s), which its schedule was built for: the
// prediction depends on the thread count and Embree's allocations, which may differ.
std::vector<int> Fit::keepMemoryBudget(std::vector<int> resolutions, const TexelSpace& init,
                                       const Checkpoint* resumed) {
  // What the process holds besides the arrays counted below, measured on five captures
  // (docs/notes/2026-11-27-memory-budget.md): the binary, its libraries, the thread pools and the
  // allocator's arenas, and per triangle what the BVH build and the light sampler's tables of the
  // emission stage leave resident.
  constexpr double kProcessBytes = 176.0 * (1 << 20), kBytesPerTriangle = 150;
  const double rays = c_.sampler == SamplerKind::Texture
                          ? static_cast<double>(c_.batchTexels + c_.materialBatchTexels + c_.highlightBatchTexels +
                                                c_.emissionBatchTexels) *
                                c_.framesPerTexel
                          : static_cast<double>(c_.imageRays);
  const double fixed = kProcessBytes + kBytesPerTriangle * static_cast<double>(w_.mesh.triangles.size()) +
                       meshBytes(w_.mesh) + static_cast<double>(w_.scene->bytes()) +
                       static_cast<double>(w_.vis.bytes()) + static_cast<double>(w_.store->mappedBytes()) +
                       pathRecordBytes(c_.maxDepth) + rays * batchBytesPerRay();
  const double sampleableFraction =
      static_cast<double>(init.sampleable.size()) / std::max<size_t>(1, init.map.texelCount());
  memoryPlan_ = planMemory(double(c_.memoryBudgetMib) * (1 << 20), resolutions, fixed,
                           static_cast<double>(w_.store->mappedBytes()), texelBytes(c_, sampleableFraction));
  if (resumed && resumed->has(kMemoryResolutionKey)) {
    std::vector<int> kept(1);
    resumed->get(kMemoryResolutionKey, kept);
    if (std::find(resolutions.begin(), resolutions.end(), kept[0]) == resolutions.end())
      fail("{}: the memory plan's resolution {} is not one of this fit's", (w_.dir / "checkpoint.bin").string(),
           kept[0]);
    if (kept[0] != memoryPlan_->resolution)
      spdlog::info("fit: the interrupted run's memory plan kept: albedo up to {}^2 (this run's would be {}^2)", kept[0],
                   memoryPlan_->resolution);
    memoryPlan_->resolution = kept[0];
  }
  std::string predicted;
  for (const MemoryEstimate& e : memoryPlan_->estimates)
    predicted += fmt::format("{} at {}^2, ", formatBytes(e.peakBytes()), e.resolution);
  spdlog::info("fit: memory budget {}: predicted peak {}the process holding {} now; albedo up to {}^2",
               formatBytes(memoryPlan_->budgetBytes), predicted, formatBytes(currentRssMiB() * (1 << 20)),
               memoryPlan_->resolution);
  // Every rank takes the root's plan: a rank with other threads or another host predicts otherwise.
  memoryPlan_->resolution = static_cast<int>(Ranks::world().rootValue(memoryPlan_->resolution));
  std::erase_if(resolutions, [&](int r) { return r > memoryPlan_->resolution; });
  finalRes_ = resolutions.back();
  return resolutions;
}

// Over MPI ranks, every rank must start from the same work folder, config and checkpoint: rank 0
// alone writes checkpoints, so on hosts without a shared filesystem the others would not resume.
void Fit::checkRanksAgree(uintmax_t checkpointBytes) const {
  if (!Ranks::world().distributed()) return;
  std::ifstream prepared(w_.dir / "prepare.json");
  const std::string preparedText{std::istreambuf_iterator<char>(prepared), std::istreambuf_iterator<char>()};
  const uint64_t fingerprint = hashTuple({std::hash<std::string>{}(c_.toJson().dump()),
                                          std::hash<std::string>{}(preparedText), checkpointBytes});
  if (!Ranks::world().agree(fingerprint))
    fail("{}: the MPI ranks read different work folders, configs or checkpoints (every host must see the same "
         "folder, on a shared filesystem)",
         w_.dir.string());
}

FitSummary Fit::run(bool resumeRequested) {
  const fs::path checkpointPath = w_.dir / "checkpoint.bin";
  std::optional<Checkpoint> checkpoint;
  if (resumeRequested && pathExists(checkpointPath)) checkpoint.emplace(Checkpoint::read(checkpointPath));
  checkRanksAgree(checkpoint ? fileSize(checkpointPath) : 0);
  const TexelSpace init(w_, w_.initResolution);
  std::vector<int> resolutions = chooseResolutions(init);
  if (c_.memoryBudgetMib > 0)
    resolutions = keepMemoryBudget(std::move(resolutions), init, checkpoint ? &*checkpoint : nullptr);
  // Valid texels scale with the area: estimated from the init resolution, no texel map needed.
  stages_ = buildSchedule(c_, resolutions, [&](int r) -> size_t {
    const size_t f = static_cast<size_t>(r / init.resolution);
    return init.sampleable.size() * f * f;
  });
  spdlog::info("fit: {} stages, final albedo resolution {}^2 ({} texels sampleable at {}^2), radiance scale {:.3g}",
               stages_.size(), finalRes_, init.sampleable.size(), init.resolution, radianceScale_);
  if (c_.timeBudget > 0) {
    std::vector<double> drawn;
    for (const Stage& st : stages_) drawn.push_back(texelsDrawn(c_, st));
    budget_.emplace(c_.timeBudget, stages_, std::move(drawn));
    spdlog::info("fit: time budget {:.0f} s: the stage lengths follow from the first iterations' cost", c_.timeBudget);
  }
  if (refinePoses_)
    spdlog::info("fit: poses refined between stages ({})",
                 c_.refinePoses == RefinePoses::On ? "refine_poses on" : "the capture's poses are estimates");
  if (gains_.estimated())
    spdlog::info("fit: frame gains estimated ({}{})", enumName(gains_.mode()),
                 c_.frameGains == FrameGainMode::Auto ? ": some 8/16-bit frames have no recorded exposure" : "");

  FitPosition at;
  std::unique_ptr<TexelSpace> space = checkpoint ? resume(*checkpoint, stages_.size(), at) : start(stages_.front());
  FitSummary summary;
  for (size_t si = at.stage; si < stages_.size(); ++si) {
    const Stage& st = stages_[si];
    if (skips(st)) continue;
    if (st.resolution != space->resolution) {
      auto finer = std::make_unique<TexelSpace>(w_, st.resolution, roles_.outOfModel);
      upsampleAlbedo(*space, *finer);
      space = std::move(finer);
    }
    if (st.emissionTexturesBefore && appearance_.emissionTextures.empty())
      allocateEmissionTextures(appearance_, w_.mesh, emissionTextureResolution(space->resolution),
                               [](float, float) { return 1.0f; });
    const int firstIteration = si == static_cast<size_t>(at.stage) ? at.iteration : 0;
    if (st.name == "materials" && firstIteration == 0) decisions_.decideHighlights(*space, batches_);
    const size_t excludedBefore = std::count(roles_.outOfModel.begin(), roles_.outOfModel.end(), 1);
    runStage(si, firstIteration, *space);
    if (static_cast<size_t>(std::count(roles_.outOfModel.begin(), roles_.outOfModel.end(), 1)) != excludedBefore)
      space = std::make_unique<TexelSpace>(w_, space->resolution, roles_.outOfModel);
    if (stopped_) {
      spdlog::info("fit: stopped after {} iterations as asked{}", globalIteration_,
                   hooks_.writeFiles ? "; continue with --resume" : "");
      summary.stopped = true;
      summary.iterations = globalIteration_;
      summary.seconds = fitSeconds();
      summary.memory = peakMemory_;
      return summary;
    }
  }
  lights_.reset();
  if (hooks_.finished) hooks_.finished(appearance_, w_.mesh);
  if (hooks_.writeFiles) summary.resultDir = writeResult(*space);
  summary.seconds = fitSeconds();
  summary.memory = peakMemory_;
  summary.iterations = globalIteration_;
  summary.finalResolution = finalRes_;
  summary.finalLoss = lastLoss_;
  for (int o = 0; o < appearance_.objectCount(); ++o)
    if (appearance_.isEmissive(o)) summary.emitters.push_back(o);
  return summary;
}

// A new fit: albedo from the init, emission from 0, the candidates for light sources.
std::unique_ptr<TexelSpace> Fit::start(const Stage& first) {
  if (hooks_.writeFiles) removeFile(w_.dir / "metrics.jsonl");
  auto space = std::make_unique<TexelSpace>(w_, first.resolution);
  appearance_.albedo = Texture(space->resolution, space->resolution, Color::Constant(0.5f));
  if (!c_.emitterParameterisation) {
    // Ablation without the emitter parameterisation: spatially varying emission on every object.
    for (Color& e : appearance_.emission) e = Color::Constant(1.0f);
    allocateEmissionTextures(appearance_, w_.mesh, emissionTextureResolution(space->resolution),
                             [](float, float) { return 0.0f; });
  }
  initialiseAlbedo(*space);
  if (gains_.estimated()) gains_.start(w_.consistencyGains());
  decisions_.excludeUnseen(*space);
  decisions_.applyHint();
  if (!c_.lights.empty()) decisions_.zeroLightAlbedo(*space);
  return space;
}

std::unique_ptr<TexelSpace> Fit::resume(const Checkpoint& ck, size_t stageCount, FitPosition& at) {
  const std::string file = (w_.dir / "checkpoint.bin").string();
  checkRunHeader(ck, c_.toJson(), file);
  CheckpointIo io = CheckpointIo::reader(ck);
  at.serialise(io, static_cast<int>(stageCount));
  if (std::find(w_.resolutions.begin(), w_.resolutions.end(), at.resolution) == w_.resolutions.end())
    fail("{}: checkpoint resolution {} is not one prepare wrote", file, at.resolution);
  globalIteration_ = at.globalIteration;
  lastLoss_ = at.loss;
  appearance_.albedo = Texture(at.resolution, at.resolution);
  serialiseState(io);  // per-object emission first: it decides which objects get emission textures
  auto space = std::make_unique<TexelSpace>(w_, at.resolution, roles_.outOfModel);
  if (at.emissionTextures) {
    allocateEmissionTextures(appearance_, w_.mesh, at.emissionTextureResolution, [](float, float) { return 1.0f; });
    serialiseState(io);
  }
  spdlog::info("fit: resumed at stage {} iteration {} from {}", at.stage, at.iteration, file);
  return space;
}

// Prepare's median radiance per texel (albedo_init.exr), at `space`'s resolution.
std::vector<float> Fit::medianRadiance(const TexelSpace& space) const {
  const Image init = w_.medianRadiance();
  std::vector<float> v(init.rgb.begin(), init.rgb.end());
  if (space.resolution == w_.initResolution) return v;
  const TexelMap initMap(w_.mesh, w_.initResolution);
  return upsampleTexels(v, initMap, space.map, w_.mesh, 3);
}

void Fit::initialiseAlbedo(const TexelSpace& space) {
  if (!c_.medianInit) return;  // ablation: mid-grey everywhere
  std::vector<float> v = medianRadiance(space);
  // The median is radiance, darker than albedo by the irradiance factor (~0.4 in a lit room): a
  // lit wall would then need an emission of its own to look right, and the emission stage would
  // find light sources everywhere. White-patch normalisation: the 95th-percentile observed texel
  // becomes albedo init_white_point (the brightest diffuse surfaces of a room are near white).
  if (c_.initWhitePoint > 0) {
    std::vector<float> lum;
    for (size_t t = 0; t < space.updatable.size(); ++t)
      if (space.updatable[t]) lum.push_back(luminance(Color(v[3 * t], v[3 * t + 1], v[3 * t + 2])));
    if (!lum.empty()) {
      std::nth_element(lum.begin(), lum.begin() + lum.size() * 95 / 100, lum.end());
      const float p95 = lum[lum.size() * 95 / 100];
      if (p95 > 0) {
        for (float& x : v) x *= c_.initWhitePoint / p95;
        spdlog::info("fit: albedo init = median radiance x {:.3g} (95th percentile {:.3g} -> {:.2f})",
                     c_.initWhitePoint / p95, p95, c_.initWhitePoint);
      }
    }
  }
  for (float& x : v) x = std::clamp(x, 0.0f, 1.0f);
  appearance_.albedo.rgb = std::move(v);
}

void Fit::upsampleAlbedo(const TexelSpace& from, const TexelSpace& to) {
  std::vector<float> values = upsampleTexels(appearance_.albedo.rgb, from.map, to.map, w_.mesh, 3);
  appearance_.albedo = Texture(to.resolution, to.resolution);
  appearance_.albedo.rgb = std::move(values);
  optimiser_.upsampleAlbedo(from, to, w_.mesh);
}

// The stages that run only when a decision before them asks for them (as far as it is known).
bool Fit::skips(const Stage& st) const {
  return (st.refit && !roles_.refitEmission) || (st.onlyWithClippedLights && !roles_.clippedLights) ||
         (st.afterClippedScale && !roles_.clippedScaleMoving);
}

// The stage's iterations, then (unless the fit stopped in it) its boundary, its gradient buffers
// freed by then.
void Fit::runStage(size_t stageIndex, int firstIteration, const TexelSpace& space) {
  iterate(stageIndex, firstIteration, space);
  if (!stopped_) finishStage(stages_[stageIndex], stageIndex, space);
}

void Fit::iterate(size_t stageIndex, int firstIteration, const TexelSpace& space) {
  // A time budget may replan this stage's length while it runs (planBudget): `st` is the
  // schedule's own entry, and every use of its length below sees the plan.
  const Stage& st = stages_[stageIndex];
  CHECK(appearance_.albedo.width == space.resolution && appearance_.albedo.rgb.size() == 3 * space.map.texelCount());
  CHECK(roles_.emitter.size() == static_cast<size_t>(appearance_.objectCount()));
  AdjointSettings settings = settings_;
  settings.mask = st.active;
  Progress progress(st.name, static_cast<size_t>(st.iterations));
  progress.advance(static_cast<size_t>(firstIteration));
  FitPhaseTimes times;
  // One buffer per stage, cleared every iteration; curvature only where the albedo steps by it.
  Gradients grads(appearance_, optimiser_.newtonAlbedo() && st.active.active(ParamKind::Albedo));
  const BatchFocus focus = st.active.active(ParamKind::Roughness)
                               ? batches_.materialFocus(space, roles_.highlight, appearance_, roles_.emitter)
                           : st.focusEmitters ? batches_.emissionFocus(space, roles_.emitter)
                                              : BatchFocus{};
  const std::vector<uint8_t> albedoHeld = decisions_.albedoHeld();
  const GradientMasks masks{space, w_.mesh, albedoHeld, roles_.highlight, roles_.emitter};
  std::vector<Color> estimates;  // each ray's, for gain_refine
  if (st.endsOnConvergence) startConvergence(stageIndex, space);
  Json stageMemory;              // the stage's largest memoryBreakdown
  if (budget_) {
    const double now = agreedFitSeconds();
    budget_->recordBoundary(now - lastIterationEnd_);
    lastIterationEnd_ = now;
  }
  // Over MPI ranks: what this rank sent, and its time in exchanges.
  const uint64_t sharedAtStart = Ranks::world().bytesShared();
  const double exchangeAtStart = Ranks::world().exchangeSeconds(), waitAtStart = Ranks::world().waitSeconds();
  for (int it = firstIteration; it < st.iterations; ++it) {
    const uint64_t iteration = static_cast<uint64_t>(globalIteration_);
    FitPhaseTimes now;
    Timer ts;
    Batch batch = batches_.sample(space, iteration, st.footprint, focus);
    gains_.apply(batch.rays, batch.frame);
    now.sample = ts.seconds();
    stats_.add(batch.stats);
    if (st.pruneAfter) decisions_.observe(batch);
    Timer tl;
    lights_ = LightSampler(*w_.scene, appearance_, lights_ ? &*lights_ : nullptr);
    now.lights = tl.seconds();
    if (lights_->builtTables() > 0)
      spdlog::debug("fit: light sampler built the tables of {} objects", lights_->builtTables());
    // gain_refine: the gains follow the albedo in the second half of each albedo stage (in the
    // emission stage the estimates start from no light).
    const bool refineGains =
        c_.gainRefine && gains_.estimated() && st.active.active(ParamKind::Albedo) && it >= st.iterations / 2;
    const GradientResult gr = computeGradients(*w_.scene, appearance_, *lights_, batch.rays, settings, iteration, grads,
                                               refineGains ? &estimates : nullptr);
    w_.scene->throwIfEmbreeFailed();
    if (refineGains) {
      std::vector<uint8_t> ownRadiance(roles_.emitter.size());
      for (size_t o = 0; o < ownRadiance.size(); ++o) ownRadiance[o] = roles_.emitter[o] || roles_.outOfModel[o];
      gains_.update(batch.rays, batch.frame, batch.object, ownRadiance, estimates);
    }
    now.primal = gr.times.primal, now.loss = gr.times.loss, now.adjoint = gr.times.adjoint;
    Timer to;
    bool averagesStart = false;
    // Every non-zero albedo gradient is at one of these: the mask and the step cost the batch
    // (listed only in the stages that step the albedo).
    const std::vector<uint32_t> splatted =
        st.active.active(ParamKind::Albedo) ? grads.splattedAlbedoTexels() : std::vector<uint32_t>{};
    for (ParamGroup& g : paramGroups(appearance_, &grads)) {
      if (!st.active.active(g.kind)) continue;
      masks.apply(g, grads.albedoCurvature, splatted);
      averagesStart |= optimiser_.step(g, grads.albedoCurvature, splatted, st, it);
    }
    grads.clear();  // for the next iteration (the buffers start zero)
    now.optimiser = to.seconds();
    times += now;
    lastLoss_ = gr.loss;
    ++globalIteration_;
    // The stage's buffers are allocated now, or the light sampler holds more than ever before (on
    // a scan, the emission stage's candidates' tables are tens of MiB from its second iteration).
    const size_t lightBytes = lights_->bytes();
    const bool lightsGrew = lightBytes > lightSamplerBytesPeak_;
    lightSamplerBytesPeak_ = std::max(lightSamplerBytesPeak_, lightBytes);
    if (it == firstIteration || averagesStart || lightsGrew) {
      const Json memory = memoryBreakdown(grads, batch, settings, space);
      spdlog::log(lightsGrew && !(it == firstIteration || averagesStart) ? spdlog::level::debug : spdlog::level::info,
                  "fit: stage {} holds {:.1f} MiB (process RSS {:.0f} MiB, peak {:.0f} MiB)", st.name,
                  memory["total"].get<double>() / (1 << 20), currentRssMiB(), peakRssMiB());
      spdlog::debug("fit: bytes by part: {}", memory.dump());
      if (peakMemory_.empty() || memory["total"] > peakMemory_["total"]) peakMemory_ = memory;
      if (stageMemory.empty() || memory["total"] > stageMemory["total"]) stageMemory = memory;
    }
    if (st.endsOnConvergence && !st.convergedAt && (it + 1) % convergenceCheckEvery(space) == 0)
      checkConvergence(stageIndex, it + 1, space, progress);
    bool go = true;
    if (hooks_.afterIteration) {
      Timer th;
      go = hooks_.afterIteration(FitIteration{st.name, globalIteration_, fitSeconds(), now, batch.rays, batch.object,
                                              *w_.scene, *lights_, settings, !grads.albedoCurvature.empty(),
                                              appearance_, w_.mesh, peakMemory_, stageMemory});
      hookSeconds_ += th.seconds();
      go = Ranks::world().allTrue(go);  // a stop on any rank stops them all at the same iteration
    }
    if (budget_) {
      const double end = agreedFitSeconds();
      budget_->recordIteration(stageIndex, end - lastIterationEnd_);
      lastIterationEnd_ = end;
      if (budget_->due(stageIndex, st, it + 1)) {
        planBudget(stageIndex, it + 1);
        progress.setTotal(static_cast<size_t>(st.iterations));
      }
    }
    if (!go) {
      if (hooks_.writeFiles) writeCheckpoint(stageIndex, it + 1, space);
      stopped_ = true;
      return;
    }
    progress.advance();
    const double traceSeconds = gr.times.primal + gr.times.adjoint;
    progress.note(fmt::format("loss {:.3e}, {} rays, {:.2f} Mrays/s", gr.loss, batch.rays.size(),
                              traceSeconds > 0 ? batch.rays.size() / traceSeconds * 1e-6 : 0.0));
    if (hooks_.writeFiles && ((it + 1) % c_.metricsEvery == 0 || it + 1 == st.iterations)) {
      Json line = {{"stage", st.name},
                   {"iteration", globalIteration_},
                   {"stage_iteration", it + 1},
                   {"loss", gr.loss},
                   {"rays", batch.rays.size()},
                   {"lr_scale", st.settles.bits != 0 ? st.settleScale(it, c_.lrFinalFraction) : 1.0f},
                   {"sampler", batch.stats.toJson()},
                   {"seconds", times.toJson()}};
      if (Ranks::world().distributed()) {
        const double n = it + 1 - firstIteration;
        line["shared_bytes_per_iteration"] = static_cast<double>(Ranks::world().bytesShared() - sharedAtStart) / n;
        line["exchange_seconds_per_iteration"] = (Ranks::world().exchangeSeconds() - exchangeAtStart) / n;
        line["exchange_wait_seconds_per_iteration"] = (Ranks::world().waitSeconds() - waitAtStart) / n;
      }
      if (st.active.active(ParamKind::Roughness))  // the fitted objects' trajectories: how settled they are
        for (int o = 0; o < appearance_.objectCount(); ++o)
          if (roles_.highlight[o])
            line["materials"][appearance_.names[o]] = {appearance_.roughness[o], appearance_.specular[o]};
      appendMetrics(line);
    }
    if (hooks_.writeFiles && (it + 1) % c_.checkpointEvery == 0 && it + 1 < st.iterations)
      writeCheckpoint(stageIndex, it + 1, space);
    if (c_.stopAfterIterations > 0 && globalIteration_ >= c_.stopAfterIterations && it + 1 < st.iterations) {
      if (hooks_.writeFiles) writeCheckpoint(stageIndex, it + 1, space);
      stopped_ = true;
      return;
    }
  }
  const int done = std::max(1, st.iterations - firstIteration);
  spdlog::info(
      "fit: stage {} done: {} iterations, loss {:.4e}; per iteration: sample {:.1f} ms, primal {:.1f} ms, adjoint "
      "{:.1f} ms, "
      "optimiser {:.1f} ms",
      st.name, st.iterations - firstIteration, lastLoss_, 1e3 * times.sample / done, 1e3 * times.primal / done,
      1e3 * times.adjoint / done, 1e3 * times.optimiser / done);
  if (Ranks::world().distributed())
    spdlog::info("fit: stage {}: rank 0 sent {} per iteration to the other ranks; exchanges took {:.1f} ms, {:.1f} of "
                 "them waiting for the slowest rank",
                 st.name, formatBytes(static_cast<double>(Ranks::world().bytesShared() - sharedAtStart) / done),
                 1e3 * (Ranks::world().exchangeSeconds() - exchangeAtStart) / done,
                 1e3 * (Ranks::world().waitSeconds() - waitAtStart) / done);
}

// The lengths of stage `stageIndex` (`done` iterations run) and those after it, for the time left
// at the cost measured (product/time_budget.h).
void Fit::planBudget(size_t stageIndex, int done) {
  std::vector<bool> runs;
  for (const Stage& st : stages_) runs.push_back(!skips(st));
  lastPlan_ = budget_->plan(stages_, stageIndex, done, agreedFitSeconds(), runs);
  std::string lengths;
  for (const Json& stage : lastPlan_["iterations"])
    lengths += fmt::format("{} {}, ", stage[0].get<std::string>(), stage[1].get<int>());
  const double scale = lastPlan_["scale"].get<double>();
  spdlog::info("fit: time budget {:.0f} s, {:.0f} s spent ({:.1f} ms per iteration of {}): {}; {}, predicted end "
               "{:.0f} s",
               c_.timeBudget, lastPlan_["elapsed_seconds"].get<double>(), lastPlan_["ms_per_iteration"].get<double>(),
               stages_[stageIndex].name, lengths.substr(0, lengths.size() - 2),
               scale == 1 ? std::string("the default schedule") : fmt::format("the default schedule x{:.2f}", scale),
               lastPlan_["predicted_end_seconds"].get<double>());
  if (hooks_.writeFiles) appendMetrics({{"budget", lastPlan_}});
}

// The albedo entries whose movement a stage ending on convergence follows: pairs of texels two
// apart in a row of the atlas, both fitted (on the frames, not held by a light) and of one object,
// up to 2^16 pairs evenly spread over them, each channel a pair. A resumed fit finds the same and
// keeps the interrupted run's last check (serialiseConvergence).
void Fit::startConvergence(size_t stageIndex, const TexelSpace& space) {
  const bool resumed = convergence_ && convergenceStage_ == static_cast<int>(stageIndex);
  const std::vector<uint8_t> fitted = fittedAlbedoTexels(space);
  std::vector<uint32_t> first;  // of each pair
  const size_t width = static_cast<size_t>(space.resolution);
  for (size_t t = 0; t < space.map.texelCount(); ++t)
    if (t % width + 2 < width && fitted[t] && fitted[t + 2] &&
        space.objectOf(t, w_.mesh) == space.objectOf(t + 2, w_.mesh))
      first.push_back(static_cast<uint32_t>(t));
  constexpr size_t kFollowedPairs = 1 << 16;
  const size_t stride = std::max<size_t>(1, first.size() / kFollowedPairs);
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (size_t k = 0; k < first.size(); k += stride)
    for (uint32_t channel = 0; channel < 3; ++channel)
      pairs.emplace_back(3 * first[k] + channel, 3 * (first[k] + 2) + channel);
  AlbedoConvergence fresh(std::move(pairs));
  if (resumed && !convergence_->lastValues().empty()) {
    if (convergence_->lastValues().size() != 2 * fresh.size())
      fail("{}: the convergence check followed {} albedo entries, this stage has {}",
           (w_.dir / "checkpoint.bin").string(), convergence_->lastValues().size(), 2 * fresh.size());
    fresh.lastValues() = std::move(convergence_->lastValues());
  }
  convergence_.emplace(std::move(fresh));
  convergenceStage_ = static_cast<int>(stageIndex);
}

// Whether stage `stageIndex`'s albedo has stopped moving by more than its noise after `done`
// iterations, and that noise is at most convergence_standard_error; if so the stage ends: at once
// when it settles nothing, else after as many iterations again (its settling half: the learning
// rates' decay and the averages need it). A settling stage is checked in its first half only.
void Fit::checkConvergence(size_t stageIndex, int done, const TexelSpace& space, Progress& progress) {
  Stage& st = stages_[stageIndex];
  CHECK(convergence_ && convergenceStage_ == static_cast<int>(stageIndex));
  if (optimiser_.albedoNewton().size() == 0) return;  // no albedo step yet
  const bool settles = st.settles.bits != 0;
  if (settles && done > st.iterations / 2) return;  // settling already
  const ParamGroup albedo = paramGroups(appearance_).front();
  const AlbedoMovement m = convergence_->check(optimiser_.albedoNewton(), albedo.hi - albedo.lo);
  const double passes = done / std::max(1e-9, iterationsPerPass(space));
  const bool converged =
      m.pairs > 0 && m.ratio <= c_.convergenceRatio && m.standardError <= c_.convergenceStandardError;
  if (hooks_.writeFiles)
    appendMetrics({{"convergence",
                    {{"stage", st.name},
                     {"stage_iteration", done},
                     {"passes", passes},
                     {"ratio", m.ratio},
                     {"movement", m.movement},
                     {"standard_error", m.standardError},
                     {"pairs", m.pairs},
                     {"converged", converged}}}});
  spdlog::debug("fit: stage {} after {} iterations ({:.1f} passes): movement {:.2f}x the noise's (median {:.4f}), "
                "median standard error {:.4f}",
                st.name, done, passes, m.ratio, m.movement, m.standardError);
  if (!converged) return;
  const int ends = settles ? 2 * done : done;
  st.convergedAt = done;
  st.iterations = ends;
  if (budget_) budget_->endStage(stageIndex, ends);
  progress.setTotal(static_cast<size_t>(st.iterations));
  spdlog::info("fit: stage {} converged after {} iterations ({:.1f} passes): its albedo moved {:.2f}x what its "
               "noise gives (at most {:.2f}), median standard error {:.4f} (at most {:.4f}); {}",
               st.name, done, passes, m.ratio, c_.convergenceRatio, m.standardError, c_.convergenceStandardError,
               ends == done ? std::string("it ends") : fmt::format("it settles until iteration {}", ends));
}

Json Fit::convergenceSummary() const {
  if (!c_.stopOnConvergence) return nullptr;
  Json j = {{"ratio", c_.convergenceRatio},
            {"standard_error", c_.convergenceStandardError},
            {"check_passes", c_.convergenceCheckPasses},
            {"stages", Json::array()}};
  for (const Stage& st : stages_)
    if (st.endsOnConvergence && !skips(st))
      j["stages"].push_back(
          {{"stage", st.name}, {"iterations", st.iterations}, {"converged_at", st.convergedAt}, {"longest", st.longest}});
  return j;
}

Json Fit::budgetSummary() const {
  if (!budget_) return nullptr;
  Json j = {{"budget_seconds", c_.timeBudget}, {"fit_seconds", fitSeconds()}};
  for (const Stage& st : stages_)
    if (!skips(st)) j["iterations"].push_back({st.name, st.iterations});
  if (!lastPlan_.is_null()) j["last_plan"] = lastPlan_;
  return j;
}

// The stage's settled groups take their averages; then the decisions at its boundary, before the
// boundary checkpoint (a run resumed from it starts the next stage with them).
void Fit::finishStage(const Stage& st, size_t stageIndex, const TexelSpace& space) {
  convergence_.reset();
  std::vector<ParamGroup> groups = paramGroups(appearance_);
  optimiser_.settle(groups, st);
  if (st.settles.active(ParamKind::Albedo)) settleAlbedoError();
  optimiser_.release(groups, st);
  if (st.settles.active(ParamKind::Albedo)) smoothAlbedo(space);
  if (st.fillUnobservedAfter) decisions_.fillUnobservedAlbedo(space);
  if (st.pruneAfter || st.redecideAfter) {
    if (decisions_.decide(space, st.name, st.pruneAfter)) optimiser_.restartAfterLightChange();
    lights_.reset();  // no table for the candidates that stopped being lights
  }
  if (st.pruneAfter && c_.emitterParameterisation && c_.clippedLightScale) decisions_.findClippedLights(space);
  if (st.scaleClippedLightsAfter && decisions_.scaleClippedLights(space, st.name)) optimiser_.restartAfterLightChange();
  // The colours from the outlines once the scale is done (the last probe that runs), so that the
  // albedo stage proper fits under them. Earlier, the probes' scales moved with them (the note).
  const bool probeFollows = stageIndex + 1 < stages_.size() && stages_[stageIndex + 1].scaleClippedLightsAfter &&
                            !skips(stages_[stageIndex + 1]);
  if (st.scaleClippedLightsAfter && !probeFollows && c_.clippedLightSilhouetteColour &&
      decisions_.colourClippedLights(st.name)) {
    optimiser_.restartAfterLightChange();
    lights_.reset();
  }
  if (st.refinePosesAfter && refinePoses_) refinePoses(st.name);
  if (hooks_.writeFiles) writeCheckpoint(stageIndex + 1, 0, space);
}

// Every kept frame aligned with the reconstruction rendered from its pose (pose_refinement.h).
void Fit::refinePoses(const std::string& after) {
  PoseAlignSettings s;
  s.width = c_.poseImageWidth, s.levels = c_.posePyramidLevels;
  FramePoses::Render render;
  render.spp = c_.poseRenderSpp, render.path = settings_.path;
  render.seed = hashTuple({c_.seed, streamTag(RandomStream::PoseRefinement), static_cast<uint64_t>(globalIteration_)});
  poses_.refine(w_, appearance_, render, gains_, s, c_.unalignedFrames == UnalignedFrames::Drop, after);
}

// The settled albedo's standard errors and unbounded values, read from the optimiser's state.
void Fit::settleAlbedoError() {
  const ParamGroup albedo = paramGroups(appearance_).front();
  CHECK(albedo.kind == ParamKind::Albedo);
  settled_.findBeyondOne(optimiser_.albedoNewton(), appearance_.albedo.rgb.size() / 3, albedo.hi - albedo.lo);
  settled_.standardError = optimiser_.albedoStandardError(albedo.hi - albedo.lo);
}

std::vector<uint8_t> Fit::fittedAlbedoTexels(const TexelSpace& space) const {
  const std::vector<uint8_t> held = decisions_.albedoHeld();
  std::vector<uint8_t> fitted(space.map.texelCount(), 0);
  for (size_t t = 0; t < fitted.size(); ++t)
    fitted[t] = space.updatable[t] && space.map.covered(t) && !held[space.objectOf(t, w_.mesh)];
  return fitted;
}

// With albedo_smoothing, the settled albedo smoothed by its standard errors
// (optim/texel_smoothing.h) on the texels whose albedo is fitted.
void Fit::smoothAlbedo(const TexelSpace& space) {
  const ParamGroup albedo = paramGroups(appearance_).front();
  CHECK(albedo.kind == ParamKind::Albedo);
  if (c_.albedoSmoothing == AlbedoSmoothing::None) return;
  if (settled_.standardError.empty()) {
    spdlog::info("fit: albedo_smoothing {} skipped: the albedo step ({}) has no standard errors",
                 enumName(c_.albedoSmoothing), enumName(c_.albedoStep));
    return;
  }
  const std::vector<uint8_t> eligible = fittedAlbedoTexels(space);
  const std::vector<float> guide =
      c_.albedoSmoothing == AlbedoSmoothing::Albedo ? std::vector<float>{} : medianRadiance(space);
  TexelSmoothingSettings settings;
  settings.radius = c_.albedoSmoothingRadius;
  SmoothedTexels s =
      smoothTexels(space.map, w_.mesh, appearance_.albedo.rgb, settled_.standardError, eligible, guide, settings);
  for (float& v : s.values) v = std::clamp(v, albedo.lo, albedo.hi);
  auto median = [](std::vector<float> e) {  // of the known errors (-1: unknown)
    std::erase_if(e, [](float x) { return x < 0; });
    return medianOf(std::move(e));
  };
  spdlog::info("fit: albedo smoothed ({}, radius {}) on {} texels; median standard error {:.4f} -> {:.4f}",
               enumName(c_.albedoSmoothing), c_.albedoSmoothingRadius, s.smoothed, median(settled_.standardError),
               median(s.standardError));
  appearance_.albedo.rgb = std::move(s.values);
  settled_.standardError = std::move(s.standardError);
}

void Fit::appendMetrics(const Json& j) const {
  std::ofstream out(w_.dir / "metrics.jsonl", std::ios::app);
  out << j.dump() << '\n';
}

// Everything a resumed fit needs besides its position: the parameters, the optimiser's state and
// what each object is.
void Fit::serialiseState(CheckpointIo& io) {
  std::vector<ParamGroup> groups = paramGroups(appearance_);
  for (ParamGroup& g : groups) io.arrayInPlace(g.name() + ".values", g.values);
  optimiser_.serialise(io, groups, appearance_.albedo.rgb.size());
  settled_.serialise(io, appearance_.albedo.rgb.size() / 3, w_.dir);
  roles_.serialise(io, w_.dir);
  gains_.serialise(io);
  poses_.serialise(io, w_);
  if (c_.stopOnConvergence) serialiseConvergence(io);
  if (budget_) {
    double elapsed = fitSeconds();
    budget_->serialise(io, elapsed, (w_.dir / "checkpoint.bin").string());
    if (!io.writing()) {
      elapsedBefore_ = lastIterationEnd_ = elapsed;
      budget_->apply(stages_);
    }
  }
}

// With stop_on_convergence: the stages' lengths (those that converged are shorter than the
// schedule's; under a time budget its plan restores them, TimeBudget::endStage having kept it in
// step) and the running stage's last check.
void Fit::serialiseConvergence(CheckpointIo& io) {
  std::vector<int> lengths, convergedAt;
  for (const Stage& st : stages_) lengths.push_back(st.iterations), convergedAt.push_back(st.convergedAt);
  io.array("convergence.stage_iterations", lengths);
  io.array("convergence.converged_at", convergedAt);
  for (size_t i = 0; i < stages_.size(); ++i) {
    const Stage& st = stages_[i];
    if (lengths[i] < 0 || convergedAt[i] < 0 || convergedAt[i] > lengths[i] ||
        (!budget_ && (st.endsOnConvergence ? lengths[i] > st.longest : lengths[i] != st.iterations)))
      fail("{}: the stage lengths do not fit this fit's schedule", (w_.dir / "checkpoint.bin").string());
    if (!budget_) stages_[i].iterations = lengths[i];
    stages_[i].convergedAt = convergedAt[i];
  }
  if (!io.optional("convergence.values", convergence_ && !convergence_->lastValues().empty())) return;
  int stage = convergenceStage_;
  size_t values = convergence_ ? convergence_->lastValues().size() : 0;
  io.single("convergence.stage", stage);
  io.single("convergence.size", values);
  if (!io.writing()) {
    if (stage < 0 || static_cast<size_t>(stage) >= stages_.size() || values > (size_t{6} << 20))
      fail("{}: the convergence check's stage or size is out of range", (w_.dir / "checkpoint.bin").string());
    convergence_.emplace(std::vector<std::pair<uint32_t, uint32_t>>{});
    convergence_->lastValues().resize(values);
    convergenceStage_ = stage;
  }
  io.array("convergence.values", convergence_->lastValues());
}

void Fit::writeCheckpoint(size_t stage, int iteration, const TexelSpace& space) {
  Checkpoint ck;
  writeRunHeader(ck, c_.toJson());
  FitPosition at{static_cast<int>(stage),
                 iteration,
                 globalIteration_,
                 space.resolution,
                 !appearance_.emissionTextures.empty(),
                 appearance_.emissionTextures.empty() ? 0 : appearance_.emissionTextures[0].fullWidth,
                 lastLoss_};
  CheckpointIo io = CheckpointIo::writer(ck);
  at.serialise(io, 0);
  if (memoryPlan_) {
    std::vector<int> resolution{memoryPlan_->resolution};
    io.array(kMemoryResolutionKey, resolution);
  }
  serialiseState(io);
  ck.write(w_.dir / "checkpoint.bin");
}

}  // namespace

FitPhaseTimes& FitPhaseTimes::operator+=(const FitPhaseTimes& o) {
  sample += o.sample, lights += o.lights, primal += o.primal, loss += o.loss, adjoint += o.adjoint,
      optimiser += o.optimiser;
  return *this;
}

Json FitPhaseTimes::toJson() const {
  return {{"sample", sample}, {"lights", lights},   {"primal", primal},
          {"loss", loss},     {"adjoint", adjoint}, {"optimiser", optimiser}};
}

FitSummary runFit(const fs::path& work, const FitConfig& config, bool resume, const FitHooks& hooks) {
  config.validate("fit config");
  Fit fit(work, config, hooks);
  return fit.run(resume);
}

}  // namespace relume
