#include "product/fit.h"

#include <spdlog/spdlog.h>

#include <array>
#include <fstream>
#include <numeric>
#include <set>
#include <variant>

#include "capture/frame_store.h"
#include "core/check.h"
#include "core/error.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/image.h"
#include "optim/adam.h"
#include "optim/checkpoint.h"
#include "optim/gauss_newton.h"
#include "optim/upsample.h"
#include "product/light_evidence.h"
#include "product/report.h"
#include "sampling/highlight_evidence.h"
#include "sampling/samplers.h"
#include "scene/atlas.h"

#include <tbb/parallel_for.h>

namespace relume {
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Config: one table of keys serves loading, validation and writing.

namespace {

using ConfigField = std::variant<int*, float*, bool*, std::string*, uint64_t*, std::vector<std::string>*>;

template <typename Fn> void forEachConfigKey(FitConfig& c, Fn&& fn) {
  fn("sampler", ConfigField(&c.sampler));
  fn("batch_texels", ConfigField(&c.batchTexels));
  fn("frames_per_texel", ConfigField(&c.framesPerTexel));
  fn("material_batch_texels", ConfigField(&c.materialBatchTexels));
  fn("highlight_batch_texels", ConfigField(&c.highlightBatchTexels));
  fn("emission_batch_texels", ConfigField(&c.emissionBatchTexels));
  fn("material_footprint", ConfigField(&c.materialFootprint));
  fn("image_rays", ConfigField(&c.imageRays));
  fn("ray_footprint", ConfigField(&c.rayFootprint));
  fn("emission_footprint", ConfigField(&c.emissionFootprint));
  fn("samples_per_ray", ConfigField(&c.samplesPerRay));
  fn("max_depth", ConfigField(&c.maxDepth));
  fn("gradients", ConfigField(&c.gradients));
  fn("emitter_gradients", ConfigField(&c.emitterGradients));
  fn("pairing", ConfigField(&c.pairing));
  fn("russian_roulette", ConfigField(&c.russianRoulette));
  fn("roulette_depth", ConfigField(&c.rouletteDepth));
  fn("albedo_step", ConfigField(&c.albedoStep));
  fn("albedo_damping", ConfigField(&c.albedoDamping));
  fn("lr_albedo", ConfigField(&c.lrAlbedo));
  fn("lr_roughness", ConfigField(&c.lrRoughness));
  fn("lr_specular", ConfigField(&c.lrSpecular));
  fn("lr_emission", ConfigField(&c.lrEmission));
  fn("lr_emission_texture", ConfigField(&c.lrEmissionTexture));
  fn("lr_final_fraction", ConfigField(&c.lrFinalFraction));
  fn("emission_floor", ConfigField(&c.emissionFloor));
  fn("masked_adam", ConfigField(&c.maskedAdam));
  fn("per_entry_steps", ConfigField(&c.perEntrySteps));
  fn("gradient_clamp", ConfigField(&c.gradientClamp));
  fn("polyak_fraction", ConfigField(&c.polyakFraction));
  fn("material_polyak_fraction", ConfigField(&c.materialPolyakFraction));
  fn("material_stage_settles", ConfigField(&c.materialStageSettles));
  fn("emission_iterations", ConfigField(&c.emissionIterations));
  fn("material_iterations", ConfigField(&c.materialIterations));
  fn("emission_texture_iterations", ConfigField(&c.emissionTextureIterations));
  fn("albedo_passes", ConfigField(&c.albedoPasses));
  fn("max_stage_iterations", ConfigField(&c.maxStageIterations));
  fn("max_resolution", ConfigField(&c.maxResolution));
  fn("light_test", ConfigField(&c.lightTest));
  fn("light_min_unexplained", ConfigField(&c.lightMinUnexplained));
  fn("light_significance", ConfigField(&c.lightSignificance));
  fn("light_min_contrast", ConfigField(&c.lightMinContrast));
  fn("light_evidence_texels", ConfigField(&c.lightEvidenceTexels));
  fn("light_redecide", ConfigField(&c.lightRedecide));
  fn("emission_refit_iterations", ConfigField(&c.emissionRefitIterations));
  fn("lights", ConfigField(&c.lights));
  fn("light_albedo_zero", ConfigField(&c.lightAlbedoZero));
  fn("prune_fraction", ConfigField(&c.pruneFraction));
  fn("emitter_radiance_fraction", ConfigField(&c.emitterRadianceFraction));
  fn("highlight_min_pairs", ConfigField(&c.highlightMinPairs));
  fn("highlight_min_contrast", ConfigField(&c.highlightMinContrast));
  fn("emitter_parameterisation", ConfigField(&c.emitterParameterisation));
  fn("median_init", ConfigField(&c.medianInit));
  fn("init_white_point", ConfigField(&c.initWhitePoint));
  fn("coarse_to_fine", ConfigField(&c.coarseToFine));
  fn("emission_textures", ConfigField(&c.emissionTextures));
  fn("emission_texture_resolution", ConfigField(&c.emissionTextureResolution));
  fn("seed", ConfigField(&c.seed));
  fn("stop_after_iterations", ConfigField(&c.stopAfterIterations));
  fn("checkpoint_every", ConfigField(&c.checkpointEvery));
  fn("metrics_every", ConfigField(&c.metricsEvery));
}

void validate(const FitConfig& c, const std::string& where) {
  auto need = [&](bool ok, const char* what) {
    if (!ok) fail("{}: {}", where, what);
  };
  need(c.sampler == "texture" || c.sampler == "image", "sampler must be texture or image");
  need(c.batchTexels >= 1 && c.batchTexels <= (1 << 24), "batch_texels must be in [1, 2^24]");
  need(c.framesPerTexel >= 1 && c.framesPerTexel <= 64, "frames_per_texel must be in [1, 64]");
  need(c.materialBatchTexels >= 0 && c.materialBatchTexels <= (1 << 24), "material_batch_texels must be in [0, 2^24]");
  need(c.highlightBatchTexels >= 0 && c.highlightBatchTexels <= (1 << 24), "highlight_batch_texels must be in [0, 2^24]");
  need(c.emissionBatchTexels >= 0 && c.emissionBatchTexels <= (1 << 24), "emission_batch_texels must be in [0, 2^24]");
  need(c.imageRays >= 1 && c.imageRays <= (1 << 24), "image_rays must be in [1, 2^24]");
  need(c.samplesPerRay >= 1 && c.samplesPerRay <= 64, "samples_per_ray must be in [1, 64]");
  need(c.maxDepth >= 0 && c.maxDepth <= 64, "max_depth must be in [0, 64]");
  need(c.rouletteDepth >= 1 && c.rouletteDepth <= 64, "roulette_depth must be in [1, 64]");
  parseGradientMode(c.gradients);
  parseEmitterGradients(c.emitterGradients);
  parsePairing(c.pairing);
  parseRayFootprint(c.rayFootprint);
  parseRayFootprint(c.materialFootprint);
  parseRayFootprint(c.emissionFootprint);
  need(c.albedoStep == "gauss-newton" || c.albedoStep == "adam", "albedo_step must be gauss-newton or adam");
  // The Gauss-Newton step models a texel's pixels as linear in the albedo at their first vertex;
  // `full` gradients add the albedo's terms at deeper vertices, which that curvature does not
  // hold (measured on the room: albedo MAE 0.24 vs 0.06 with direct).
  need(c.albedoStep != "gauss-newton" || c.gradients == "direct", "gradients full needs albedo_step adam");
  need(std::isfinite(c.albedoDamping) && c.albedoDamping > 0 && c.albedoDamping <= 1, "albedo_damping must be in (0, 1]");
  need(c.lrFinalFraction > 0 && c.lrFinalFraction <= 1, "lr_final_fraction must be in (0, 1]");
  for (float lr : {c.lrAlbedo, c.lrRoughness, c.lrSpecular, c.lrEmission, c.lrEmissionTexture})
    need(std::isfinite(lr) && lr > 0 && lr <= 10, "learning rates must be in (0, 10]");
  need(std::isfinite(c.emissionFloor) && c.emissionFloor > 0 && c.emissionFloor <= 1, "emission_floor must be in (0, 1]");
  need(std::isfinite(c.gradientClamp) && c.gradientClamp >= 0, "gradient_clamp must be >= 0 (0 = off)");
  need(c.polyakFraction >= 0 && c.polyakFraction <= 1, "polyak_fraction must be in [0, 1]");
  need(c.materialPolyakFraction >= 0 && c.materialPolyakFraction <= 1, "material_polyak_fraction must be in [0, 1]");
  need(c.emissionIterations >= 0 && c.materialIterations >= 0 && c.emissionTextureIterations >= 0 &&
           c.maxStageIterations >= 1,
       "stage lengths must be >= 0 (max_stage_iterations >= 1)");
  need(std::isfinite(c.albedoPasses) && c.albedoPasses > 0 && c.albedoPasses <= 1e4, "albedo_passes must be in (0, 1e4]");
  need(c.maxResolution >= 0, "max_resolution must be >= 0");
  need(c.emissionTextureResolution >= 0, "emission_texture_resolution must be >= 0 (0 = the albedo's)");
  need(c.initWhitePoint >= 0 && c.initWhitePoint <= 1, "init_white_point must be in [0, 1] (0 = off)");
  need(c.lightTest == "reflector" || c.lightTest == "radiance_fraction", "light_test must be reflector or radiance_fraction");
  need(c.lightMinUnexplained >= 0 && c.lightMinUnexplained <= 1, "light_min_unexplained must be in [0, 1]");
  need(std::isfinite(c.lightSignificance) && c.lightSignificance >= 0, "light_significance must be >= 0");
  need(std::isfinite(c.lightMinContrast) && c.lightMinContrast >= 0, "light_min_contrast must be >= 0");
  need(c.lightEvidenceTexels >= 1 && c.lightEvidenceTexels <= (1 << 20), "light_evidence_texels must be in [1, 2^20]");
  need(c.emissionRefitIterations >= 0, "emission_refit_iterations must be >= 0");
  need(std::set<std::string>(c.lights.begin(), c.lights.end()).size() == c.lights.size(), "lights names an object twice");
  need(c.pruneFraction >= 0 && c.pruneFraction < 1, "prune_fraction must be in [0, 1)");
  need(c.emitterRadianceFraction >= 0 && c.emitterRadianceFraction <= 1, "emitter_radiance_fraction must be in [0, 1]");
  need(c.highlightMinPairs >= 1, "highlight_min_pairs must be >= 1");
  need(std::isfinite(c.highlightMinContrast), "highlight_min_contrast must be finite");
  need(c.checkpointEvery >= 1 && c.metricsEvery >= 1, "checkpoint_every and metrics_every must be >= 1");
  need(c.stopAfterIterations >= 0, "stop_after_iterations must be >= 0 (0 = run to the end)");
}

}  // namespace

FitConfig FitConfig::load(const fs::path& path) { return fromJson(readJson(path), path.string(), FitConfig{}); }

FitConfig FitConfig::fromJson(const Json& j, const std::string& where, FitConfig c) {
  if (!j.is_object()) fail("{}: a fit config is a JSON object", where);
  std::set<std::string> known;
  forEachConfigKey(c, [&](const char* key, ConfigField field) {
    known.insert(key);
    if (!j.contains(key)) return;
    const Json& v = j[key];
    std::visit(
        [&](auto* p) {
          using T = std::remove_pointer_t<decltype(p)>;
          bool ok = false;
          if constexpr (std::is_same_v<T, std::vector<std::string>>)
            ok = v.is_array() && std::all_of(v.begin(), v.end(), [](const Json& e) { return e.is_string(); });
          else
            ok = std::is_same_v<T, bool>          ? v.is_boolean()
                 : std::is_same_v<T, std::string> ? v.is_string()
                 : std::is_same_v<T, float>       ? v.is_number()
                                                  : v.is_number_integer();
          if (!ok) fail("{}: '{}' has the wrong type ({})", where, key, v.type_name());
          *p = v.get<T>();
        },
        field);
  });
  for (const auto& [key, value] : j.items())
    if (!known.count(key)) fail("{}: unknown key '{}' (see the README's fit config table)", where, key);
  validate(c, where);
  return c;
}

Json FitConfig::toJson() const {
  Json j = Json::object();
  forEachConfigKey(const_cast<FitConfig&>(*this), [&](const char* key, ConfigField field) {
    std::visit([&](auto* p) { j[key] = *p; }, field);
  });
  return j;
}

// ---------------------------------------------------------------------------------------------

namespace {

constexpr int kCheckpointVersion = 3;  // 3: light decisions, out-of-model objects
constexpr uint64_t kHighlightProbeBatches = 16;

// A checkpoint continues the run its config describes; where to stop is not part of the run.
bool sameRun(Json a, Json b) {
  a.erase("stop_after_iterations"), b.erase("stop_after_iterations");
  return a == b;
}

// Everything prepare built, loaded once.
struct Workspace {
  fs::path dir;
  Json prepare;
  TriangleMesh mesh;
  std::unique_ptr<Scene> scene;
  std::vector<Frame> frames;
  std::unique_ptr<FrameStore> store;
  VisibilityIndex vis;
  int initResolution = 0;
  std::vector<int> resolutions;
  std::vector<float> coverage;  // observations per texel at the init resolution
  std::vector<std::pair<int, std::string>> names;  // object id, name
  std::vector<uint32_t> kept;

  explicit Workspace(const fs::path& work) : dir(work) {
    const fs::path pj = work / "prepare.json";
    if (!fs::exists(pj)) fail("{}: no prepare.json; run `relume prepare CAPTURE --out {}` first", work.string(), work.string());
    prepare = readJson(pj);
    for (const char* f : {"atlas_mesh.ply", "frames.bin", "visibility.bin", "albedo_init.exr", "coverage.exr"})
      if (!fs::exists(work / f)) fail("{}: missing {}; rerun `relume prepare`", work.string(), f);
    withJsonErrors(pj, [&] {
      const fs::path capture = prepare.at("capture").get<std::string>();
      frames = readTransforms(capture / "transforms.json").frames;
      kept = jsonIntegers<uint32_t>(prepare.at("phases").at("frames").at("kept"), 0, UINT32_MAX, pj.string(), "kept");
      resolutions = jsonIntegers<int>(prepare.at("resolutions"), 1, kMaxTextureResolution, pj.string(), "resolutions");
      if (resolutions.empty()) fail("{}: no resolutions; rerun `relume prepare`", pj.string());
      const Json objectNames = prepare["phases"]["atlas"].value("object_names", Json::object());
      for (const auto& [id, name] : objectNames.items())
        names.push_back({static_cast<int>(jsonInteger(Json::parse(id, nullptr, false), 0, INT32_MAX, pj.string(), "object_names")),
                         name.get<std::string>()});
      return 0;
    });
    mesh = loadMesh(work / "atlas_mesh.ply");
    scene = std::make_unique<Scene>(mesh);
    store = std::make_unique<FrameStore>(work / "frames.bin");
    if (store->frameCount() != frames.size())
      fail("{}: frames.bin has {} frames but transforms.json {}; rerun `relume prepare`", work.string(), store->frameCount(),
           frames.size());
    for (uint32_t k : kept)
      if (k >= frames.size()) fail("{}: prepare.json keeps frame {} of {}", pj.string(), k, frames.size());
    vis = VisibilityIndex::read(work / "visibility.bin");
    initResolution = vis.resolution;
    const Image cov = readImage(work / "coverage.exr");
    if (cov.width != initResolution || cov.height != initResolution)
      fail("{}: coverage.exr is {}x{}, expected {}^2", work.string(), cov.width, cov.height, initResolution);
    coverage.resize(static_cast<size_t>(initResolution) * initResolution);
    for (size_t t = 0; t < coverage.size(); ++t) coverage[t] = cov.rgb[3 * t];
    if (kept.empty()) fail("{}: prepare dropped every frame (see prepare.json)", work.string());
  }

  // Observations of the init-resolution texel that contains texel t of a `res` map.
  float coverageOf(size_t t, int res) const {
    const int s = res / initResolution;
    const size_t x = (t % res) / s, y = (t / res) / s;
    return coverage[y * initResolution + x];
  }
  TrainingFrames trainingFrames() const { return {&frames, store.get(), kept}; }
};

// The albedo texels of one resolution: the texel map, which texels may be sampled (covered and
// observed) and which may be updated (also the dilated ring, read by bilinear lookups).
struct TexelSpace {
  int resolution = 0;
  TexelMap map;
  std::vector<uint32_t> sampleable;
  std::vector<uint8_t> updatable;
  // Texels of `excluded` objects (out of the model: light_evidence.h) are neither sampled nor updated.
  TexelSpace(const Workspace& w, int res, const std::vector<uint8_t>& excluded = {})
      : resolution(res), map(w.mesh, res), updatable(map.texelCount(), 0) {
    for (size_t t = 0; t < map.texelCount(); ++t) {
      if (!map.valid(t) || w.coverageOf(t, res) <= 0) continue;
      if (!excluded.empty() && excluded[w.mesh.faceObject[map.triangle(t)]]) continue;
      updatable[t] = 1;
      if (map.covered(t)) sampleable.push_back(static_cast<uint32_t>(t));
    }
    if (sampleable.empty()) fail("{}: no texel of the mesh was observed by any kept frame", w.dir.string());
  }
};

struct Stage {
  std::string name;
  ParamMask active;
  int resolution = 0;  // albedo resolution during the stage
  int iterations = 0;
  bool pruneAfter = false, emissionTexturesBefore = false;
  // The unknowns this stage settles (lr decay over its second half, Polyak averaging, then the
  // average kept): each kind settles in the last stage that fits it.
  ParamMask settles{0};
  RayFootprint footprint = RayFootprint::Point;  // what the uniform batch's rays are compared with
  bool redecideAfter = false;   // the light sources are decided again at its end
  bool refit = false;           // emission only, run when the re-decision changed the light sources
  bool focusEmitters = false;   // draws emission_batch_texels from the light-source candidates
  bool fillUnobservedAfter = false;  // unobserved texels take their object's mean albedo at its end
};

// The resolution the frames resolve: the smallest stage resolution whose texel is no larger than
// the median footprint of an observed pixel on the surface.
int resolvedResolution(const Workspace& w, const Batch& batch) {
  std::vector<float> footprint;
  for (const BatchRay& r : batch.rays) {
    const auto hit = w.scene->intersect(r.origin, r.dir);
    if (!hit) continue;
    const Camera* cam = nullptr;
    for (uint32_t k : w.kept)
      if ((w.frames[k].camera.position - r.origin).squaredNorm() == 0.0f) cam = &w.frames[k].camera;
    if (!cam) continue;
    // Pixel footprint on the surface: distance / focal length, stretched by the obliquity.
    footprint.push_back(hit->t / cam->fx / std::max(0.2f, std::abs(hit->ng.dot(r.dir))));
  }
  const double texelsPerMetreInit = w.prepare["phases"]["atlas"].value("texels_per_metre", 0.0) *
                                    w.initResolution / w.prepare["phases"]["atlas"].value("gutter_resolution", AtlasOptions{}.gutterResolution);
  if (footprint.empty() || texelsPerMetreInit <= 0) return w.resolutions.back();
  std::nth_element(footprint.begin(), footprint.begin() + footprint.size() / 2, footprint.end());
  const double pixelMetres = footprint[footprint.size() / 2];
  for (int r : w.resolutions)
    if (1.0 / (texelsPerMetreInit * r / w.initResolution) <= pixelMetres) return r;
  return w.resolutions.back();
}

std::vector<Stage> buildSchedule(const FitConfig& c, const std::vector<int>& resolutions, const Workspace& w,
                                 const std::function<size_t(int)>& sampleableAt) {
  using K = ParamKind;
  const int finalRes = resolutions.back();
  auto albedoIterations = [&](int res) {
    const double n = std::ceil(c.albedoPasses * sampleableAt(res) / std::max(1, c.sampler == "texture" ? c.batchTexels : c.imageRays));
    return static_cast<int>(std::clamp(n, 1.0, static_cast<double>(c.maxStageIterations)));
  };
  std::vector<Stage> s;
  const RayFootprint rays = parseRayFootprint(c.rayFootprint);
  const ParamMask emission = c.emitterParameterisation ? ParamMask::only({K::Emission}) : ParamMask::only({K::EmissionTexture});
  if (!c.coarseToFine) {
    ParamMask all = ParamMask::only({K::Albedo, K::Roughness, K::Specular});
    all.bits |= emission.bits;
    int n = c.emissionIterations + c.materialIterations;
    for (int r : resolutions) n += albedoIterations(r);
    s.push_back({"all", all, finalRes, n, false, false, all, rays});
    return s;
  }
  // Its unknowns are per object (with emitter_parameterisation), so a ray may stand for a whole
  // pixel: an emitter seen as a few pixels is mixed with its surroundings in every one of them,
  // and a ray through the emitter's own point compared with that mixture dims it (README
  // "Pixel filters"). Per-texel unknowns are better served by points: a pixel ray's residual and
  // sensitivity belong to different texels, noise a per-texel step cannot average away.
  s.push_back({"emission", emission, resolutions.front(), c.emissionIterations, c.emitterParameterisation, false, {0},
               parseRayFootprint(c.emissionFootprint)});
  // Then the albedo at the first resolution, and only then roughness and specular with it: while
  // the albedo is still near its (too dark) init, the specular lobe of a rough object makes up
  // for it (measured on the room: the walls' specular went to 1.0 whether it was fitted before or
  // together with the first albedo steps).
  // Emission stays where stage 1 put it: there the emitters are pinned by the frames that see them
  // (I = E), while fitted together with the albedo it drifts along the near-null direction
  // "brighter lights, darker albedo" (room: 3% after stage 1, 10% after the albedo stages).
  const ParamMask albedo = ParamMask::only({K::Albedo});
  s.push_back({fmt::format("albedo@{}", resolutions.front()), albedo, resolutions.front(), albedoIterations(resolutions.front())});
  // The light sources decided again now that the albedo explains the lit surfaces; when that
  // changed them, their emission is fitted again (the albedo held) before the materials.
  const bool redecide = c.emitterParameterisation && c.lightTest == "reflector" && c.lightRedecide && c.lights.empty();
  s.back().redecideAfter = redecide;
  // The fill belongs to the reflector test's light estimate (with the hint too, so the two compare).
  s.front().fillUnobservedAfter = s.back().fillUnobservedAfter = c.lightTest == "reflector";
  const size_t refitStage = s.size();
  if (redecide && c.emissionRefitIterations > 0)
    s.push_back({"emission_refit", emission, resolutions.front(), c.emissionRefitIterations});
  // With material_stage_settles, roughness and specular settle in their own stage and the finer
  // albedo stages fit the albedo alone: the material texels make the 1K room's albedo@1024
  // iterations 1.3x dearer, but without them its albedo came out worse (README).
  const ParamMask materials = ParamMask::only({K::Albedo, K::Roughness, K::Specular});
  const ParamMask afterMaterials = c.materialStageSettles ? albedo : materials;
  const size_t materialStage = s.size();
  s.push_back({"materials", materials, resolutions.front(), c.materialIterations});
  for (size_t i = 1; i < resolutions.size(); ++i)
    s.push_back({fmt::format("albedo@{}", resolutions[i]), afterMaterials, resolutions[i], albedoIterations(resolutions[i])});
  s.back().settles = s.back().active;
  if (c.materialStageSettles) {
    s[materialStage].settles.set(K::Roughness, true);
    s[materialStage].settles.set(K::Specular, true);
  }
  if (c.emitterParameterisation && c.emissionTextures && c.emissionTextureIterations > 0) {
    const ParamMask textures = ParamMask::only({K::EmissionTexture});
    s.push_back({"emission_texture", textures, finalRes, c.emissionTextureIterations, false, true, textures});
  }
  for (size_t i = 1; i < s.size(); ++i) s[i].footprint = rays;  // every stage after the emission stage
  s[0].focusEmitters = c.emitterParameterisation;
  if (refitStage < s.size() && s[refitStage].name == "emission_refit") {
    s[refitStage].refit = s[refitStage].focusEmitters = true;
    s[refitStage].footprint = s[0].footprint;
  }
  return s;
}

class Fit {
 public:
  Fit(const fs::path& work, const FitConfig& config, const FitHooks& hooks)
      : c_(config), hooks_(hooks), w_(work), appearance_(w_.mesh.objectCount) {
    settings_.mode = parseGradientMode(c_.gradients);
    settings_.emitters = parseEmitterGradients(c_.emitterGradients);
    settings_.pairing = parsePairing(c_.pairing);
    settings_.path.maxDepth = c_.maxDepth;
    settings_.path.russianRoulette = c_.russianRoulette;
    settings_.path.rouletteDepth = c_.rouletteDepth;
    settings_.seed = c_.seed;
    for (const auto& [id, name] : w_.names)
      if (id >= 0 && id < appearance_.objectCount()) appearance_.names[id] = name;
    std::fill(appearance_.albedoFromTexture.begin(), appearance_.albedoFromTexture.end(), 1);
    emitter_.assign(appearance_.objectCount(), 1);
    outOfModel_.assign(appearance_.objectCount(), 0);
    observedSum_.assign(appearance_.objectCount(), 0.0);
    observedCount_.assign(appearance_.objectCount(), 0);
    highlight_.assign(appearance_.objectCount(), 0);
    highlightPairs_.assign(appearance_.objectCount(), 0), highlightContrast_.assign(appearance_.objectCount(), 0.0);
  }

  FitSummary run(bool resume) {
    const fs::path checkpointPath = w_.dir / "checkpoint.bin";
    // Resolutions: the prepared ones up to what the frames resolve (or the cap).
    TexelSpace init(w_, w_.initResolution);
    {
      TextureSpaceSampler probe(*w_.scene, init.map, init.sampleable, w_.vis, w_.trainingFrames());
      const Batch b = probe.sample(c_.seed, 0xFFFFFFFF, {std::min(c_.batchTexels, 4096), c_.framesPerTexel, footprint_});
      finalRes_ = c_.maxResolution > 0 ? c_.maxResolution : resolvedResolution(w_, b);
      // The brightest observation sets the scale of emission steps (lights are what is brightest).
      if (b.rays.empty()) fail("{}: no frame connection survived (every texel occluded or off-frame?)", w_.dir.string());
      for (const BatchRay& r : b.rays)
        if (std::isfinite(r.reference.maxCoeff())) radianceScale_ = std::max(radianceScale_, r.reference.maxCoeff());
    }
    std::vector<int> resolutions;
    for (int r : w_.resolutions)
      if (r <= finalRes_) resolutions.push_back(r);
    if (resolutions.empty()) fail("fit: max_resolution {} is below the init resolution {}", finalRes_, w_.initResolution);
    if (!c_.coarseToFine) resolutions = {resolutions.back()};
    finalRes_ = resolutions.back();
    auto sampleableAt = [&](int r) -> size_t {
      // Valid texels scale with the area: estimate from the init resolution, no texel map needed.
      const size_t f = static_cast<size_t>(r / init.resolution);
      return init.sampleable.size() * f * f;
    };
    const std::vector<Stage> stages = buildSchedule(c_, resolutions, w_, sampleableAt);
    spdlog::info("fit: {} stages, final albedo resolution {}^2 ({} texels sampleable at {}^2), radiance scale {:.3g}",
                 stages.size(), finalRes_, init.sampleable.size(), init.resolution, radianceScale_);

    // Initial state, or the checkpoint's.
    int startStage = 0, startIteration = 0;
    std::unique_ptr<TexelSpace> space;
    if (resume && fs::exists(checkpointPath)) {
      const Checkpoint ck = Checkpoint::read(checkpointPath);
      if (ck.meta.value("version", 0) != kCheckpointVersion || !sameRun(ck.meta.value("config", Json()), c_.toJson()))
        fail("{}: checkpoint was written with another config; rerun without --resume", checkpointPath.string());
      startStage = static_cast<int>(ck.metaInteger("stage", 0, static_cast<int64_t>(stages.size())));
      startIteration = static_cast<int>(ck.metaInteger("iteration", 0, INT32_MAX));
      globalIteration_ = static_cast<int>(ck.metaInteger("global_iteration", 0, INT32_MAX));
      const int res = static_cast<int>(ck.metaInteger("resolution", 1, kMaxTextureResolution));
      if (std::find(w_.resolutions.begin(), w_.resolutions.end(), res) == w_.resolutions.end())
        fail("{}: checkpoint resolution {} is not one prepare wrote", checkpointPath.string(), res);
      appearance_.albedo = Texture(res, res);
      restore(ck);  // per-object emission first: it decides which objects get emission textures
      space = std::make_unique<TexelSpace>(w_, res, outOfModel_);
      if (ck.meta.value("emission_textures", false)) {
        const int emissionRes = static_cast<int>(ck.metaInteger("emission_texture_resolution", 1, kMaxTextureResolution));
        allocateEmissionTextures(appearance_, w_.mesh, emissionRes,
                                 [](float, float) { return 1.0f; });
        restore(ck);
      }
      spdlog::info("fit: resumed at stage {} iteration {} from {}", startStage, startIteration, checkpointPath.string());
    } else {
      if (hooks_.writeFiles) fs::remove(w_.dir / "metrics.jsonl");
      space = std::make_unique<TexelSpace>(w_, stages.front().resolution);
      appearance_.albedo = Texture(space->resolution, space->resolution, Color::Constant(0.5f));
      if (!c_.emitterParameterisation) {
        // Ablation without the emitter parameterisation: spatially varying emission on every object.
        for (Color& e : appearance_.emission) e = Color::Constant(1.0f);
        allocateEmissionTextures(appearance_, w_.mesh, emissionTextureResolution(space->resolution), [](float, float) { return 0.0f; });
      }
      initialiseAlbedo(*space);
      excludeUnseenEmitters(*space);
      applyLightsHint();
      if (!c_.lights.empty()) zeroLightAlbedo(*space);
    }

    FitSummary summary;
    for (size_t si = startStage; si < stages.size(); ++si) {
      const Stage& st = stages[si];
      if (st.refit && !refitEmission_) continue;
      if (st.resolution != space->resolution) {
        auto finer = std::make_unique<TexelSpace>(w_, st.resolution, outOfModel_);
        upsampleAlbedo(*space, *finer);
        space = std::move(finer);
      }
      if (st.emissionTexturesBefore && appearance_.emissionTextures.empty())
        allocateEmissionTextures(appearance_, w_.mesh, emissionTextureResolution(space->resolution), [](float, float) { return 1.0f; });
      if (st.name == "materials" && startIteration == 0) decideHighlights(*space);
      const size_t excludedBefore = std::count(outOfModel_.begin(), outOfModel_.end(), 1);
      runStage(st, si, si == static_cast<size_t>(startStage) ? startIteration : 0, *space, checkpointPath);
      if (static_cast<size_t>(std::count(outOfModel_.begin(), outOfModel_.end(), 1)) != excludedBefore)
        space = std::make_unique<TexelSpace>(w_, space->resolution, outOfModel_);
      if (stopped_) {
        spdlog::info("fit: stopped after {} iterations as asked{}", globalIteration_,
                     hooks_.writeFiles ? "; continue with --resume" : "");
        summary.stopped = true;
        summary.iterations = globalIteration_;
        summary.seconds = fitSeconds();
        summary.memory = peakMemory_;
        return summary;
      }
      startIteration = 0;
    }
    lights_.reset();
    if (hooks_.finished) hooks_.finished(appearance_, w_.mesh);
    if (hooks_.writeFiles) {
      summary.resultDir = writeResult(*space);
      if (hooks_.report) writeFitReport(w_.dir);
    }
    summary.seconds = fitSeconds();
    summary.memory = peakMemory_;
    summary.iterations = globalIteration_;
    summary.finalResolution = finalRes_;
    summary.finalLoss = lastLoss_;
    for (int o = 0; o < appearance_.objectCount(); ++o)
      if (appearance_.isEmissive(o)) summary.emitters.push_back(o);
    return summary;
  }

 private:
  void initialiseAlbedo(const TexelSpace& space) {
    if (!c_.medianInit) return;  // ablation: mid-grey everywhere
    const Image init = readImage(w_.dir / "albedo_init.exr");
    if (init.width != w_.initResolution) fail("{}: albedo_init.exr has the wrong size", w_.dir.string());
    std::vector<float> v(init.rgb.begin(), init.rgb.end());
    if (space.resolution != w_.initResolution) {
      const TexelMap initMap(w_.mesh, w_.initResolution);
      v = upsampleTexels(v, initMap, space.map, w_.mesh, 3);
    }
    // The median is radiance, darker than albedo by the irradiance factor (~0.4 in a lit room): a
    // lit wall would then need an emission of its own to look right, and the emission stage would
    // find light sources everywhere. White-patch normalisation: the 95th-percentile observed
    // texel becomes albedo init_white_point (the brightest diffuse surfaces of a room are near white).
    if (c_.initWhitePoint > 0) {
      std::vector<float> lum;
      for (size_t t = 0; t < space.updatable.size(); ++t)
        if (space.updatable[t]) lum.push_back(luminance(Color(v[3 * t], v[3 * t + 1], v[3 * t + 2])));
      if (!lum.empty()) {
        std::nth_element(lum.begin(), lum.begin() + lum.size() * 95 / 100, lum.end());
        const float p95 = lum[lum.size() * 95 / 100];
        if (p95 > 0) {
          for (float& x : v) x *= c_.initWhitePoint / p95;
          spdlog::info("fit: albedo init = median radiance x {:.3g} (95th percentile {:.3g} -> {:.2f})", c_.initWhitePoint / p95,
                       p95, c_.initWhitePoint);
        }
      }
    }
    for (float& x : v) x = std::clamp(x, 0.0f, 1.0f);
    appearance_.albedo.rgb = std::move(v);
  }

  // Values and Adam state move to the finer resolution; m and v are rescaled because each child
  // texel receives about 1/f^2 of its parent's splat weight (keeps m / sqrt(v), the step, the same).
  void upsampleAlbedo(const TexelSpace& from, const TexelSpace& to) {
    const float f2 = static_cast<float>(to.resolution) / from.resolution * static_cast<float>(to.resolution) / from.resolution;
    std::vector<float> values = upsampleTexels(appearance_.albedo.rgb, from.map, to.map, w_.mesh, 3);
    appearance_.albedo = Texture(to.resolution, to.resolution);
    appearance_.albedo.rgb = std::move(values);
    if (newton_.size() > 0) {  // each child texel receives ~1/f^2 of its parent's curvature, as of its gradient
      GaussNewtonState up;
      up.numerator = upsampleTexels(newton_.numerator, from.map, to.map, w_.mesh, 3);
      up.curvature = upsampleTexels(newton_.curvature, from.map, to.map, w_.mesh, 3);
      for (float& n : up.numerator) n /= f2;
      for (float& h : up.curvature) h /= f2;
      up.steps = upsampleSteps(newton_.steps, from, to);
      newton_ = std::move(up);
    }
    if (auto it = adam_.find("albedo"); it != adam_.end()) {
      AdamState& s = it->second;
      AdamState up;
      up.m = upsampleTexels(s.m, from.map, to.map, w_.mesh, 3);
      up.v = upsampleTexels(s.v, from.map, to.map, w_.mesh, 3);
      for (float& m : up.m) m /= f2;
      for (float& v : up.v) v /= f2 * f2;
      up.steps = upsampleSteps(s.steps, from, to);
      s = std::move(up);
    }
    polyak_.erase("albedo");
  }

  std::vector<uint16_t> upsampleSteps(const std::vector<uint16_t>& steps, const TexelSpace& from, const TexelSpace& to) const {
    const std::vector<float> up = upsampleTexels(std::vector<float>(steps.begin(), steps.end()), from.map, to.map, w_.mesh, 3);
    std::vector<uint16_t> out(up.size());
    for (size_t i = 0; i < up.size(); ++i) out[i] = static_cast<uint16_t>(std::lround(up[i]));
    return out;
  }

  bool newtonAlbedo() const { return c_.albedoStep == "gauss-newton"; }

  // Emission textures cover each emitter's uv window; an emitter with a large window (a wall
  // wrongly kept as a light, a window) would otherwise hold a 4096^2-scale texture with its Adam
  // state, gradient and average (measured: 4.3-4.9 GB held at 4096^2 when weak emitters survived).
  int emissionTextureResolution(int albedoResolution) const {
    return c_.emissionTextureResolution > 0 ? std::min(albedoResolution, c_.emissionTextureResolution) : albedoResolution;
  }

  AdamSettings adamFor(const ParamGroup& g, float lrScale) const {
    AdamSettings s;
    s.masked = c_.maskedAdam;
    s.perEntrySteps = c_.perEntrySteps;
    switch (g.kind) {
      case ParamKind::Albedo: s.learningRate = c_.lrAlbedo; break;
      case ParamKind::Roughness: s.learningRate = c_.lrRoughness; break;
      case ParamKind::Specular: s.learningRate = c_.lrSpecular; break;
      case ParamKind::Emission:
      case ParamKind::EmissionTexture:
        s.learningRate = g.kind == ParamKind::Emission ? c_.lrEmission : c_.lrEmissionTexture;
        s.relativeFloor = c_.emissionFloor * radianceScale_;
        break;
    }
    s.learningRate *= lrScale;
    return s;
  }

  // Zeroes the gradient of entries that must not move: unobserved texels, light sources' albedo
  // (light_albedo_zero; also its Gauss-Newton curvature, with which a texel still moves towards its
  // running fit), pruned emitters, objects whose highlights were never seen.
  void maskGradients(ParamGroup& g, std::vector<float>& albedoCurvature, const TexelSpace& space,
                     std::span<const uint32_t> splattedAlbedo) const {
    switch (g.kind) {
      case ParamKind::Albedo:
        for (uint32_t t : splattedAlbedo) {
          const bool held = albedoHeld(w_.mesh.faceObject[space.map.triangle(t)]);
          if (!space.updatable[t] || held) std::fill_n(g.grads.begin() + 3 * static_cast<ptrdiff_t>(t), 3, 0.0f);
          if (held && !albedoCurvature.empty()) std::fill_n(albedoCurvature.begin() + 3 * static_cast<ptrdiff_t>(t), 3, 0.0f);
        }
        break;
      case ParamKind::Roughness:
      case ParamKind::Specular:
        for (size_t o = 0; o < highlight_.size(); ++o)
          if (!highlight_[o]) g.grads[o] = 0.0f;
        break;
      case ParamKind::Emission:
        for (size_t o = 0; o < emitter_.size(); ++o)
          if (!emitter_[o]) g.grads[3 * o] = g.grads[3 * o + 1] = g.grads[3 * o + 2] = 0.0f;
        break;
      case ParamKind::EmissionTexture: break;
    }
  }

  // The sampleable texels of the objects whose roughness and specular are fitted.
  std::vector<uint32_t> fittedObjectTexels(const TexelSpace& space) const {
    std::vector<uint32_t> texels;
    for (uint32_t t : space.sampleable)
      if (highlight_[w_.mesh.faceObject[space.map.triangle(t)]]) texels.push_back(t);
    return texels;
  }

  // The texels a stage draws more of: in the material stage the fitted objects'
  // (material_batch_texels) and their highlights (highlight_batch_texels); in the emission stage
  // each light-source candidate's own (emission_batch_texels, shared evenly between them).
  struct BatchFocus {
    std::vector<uint32_t> objects, highlights;
    std::vector<std::vector<uint32_t>> candidates;
  };

  // Highlight texels: each fitted texel is connected to every frame that sees it (8 draws per
  // texel, so one is missed with p ~ 3e-4) and kept if one of those connections sees a light
  // reflected. Depends on the geometry, the frames and the emitter set only, so a resumed fit
  // finds the same texels.
  BatchFocus materialFocus(const TexelSpace& space) const {
    BatchFocus f{fittedObjectTexels(space), {}, {}};
    if (f.objects.empty() || c_.highlightBatchTexels == 0) return f;
    const TextureSpaceSampler all(*w_.scene, space.map, f.objects, w_.vis, w_.trainingFrames());
    const int draws = static_cast<int>(std::min<size_t>(8 * f.objects.size(), 1 << 24));
    const Batch b = all.sample(hashTuple({c_.seed, 0x70726f}), 0, {draws, 1 << 20, RayFootprint::Point});
    std::vector<uint8_t> lit(space.map.texelCount(), 0);
    tbb::parallel_for(size_t{0}, b.rays.size(), [&](size_t j) {
      if (seesLightReflected(b.rays[j]) == 1) lit[b.texel[b.slot[j]]] = 1;  // benign race: every writer stores 1
    });
    for (uint32_t t : f.objects)
      if (lit[t]) f.highlights.push_back(t);
    spdlog::info("fit: {} of the fitted objects' {} texels show a light reflected", f.highlights.size(), f.objects.size());
    return f;
  }

  // An object's emission is decided by its own pixels, but a uniform batch holds them in
  // proportion to its area: a lamp of 6 texels among 75,000 is in one batch out of two, and its
  // emission follows the walls it lights instead, through an albedo still at its init (the flower
  // bedroom's lamp: 293 for a truth of 1000, then pruned as lit).
  BatchFocus emissionFocus(const TexelSpace& space) const {
    BatchFocus f;
    if (c_.emissionBatchTexels == 0) return f;
    std::vector<std::vector<uint32_t>> texels(appearance_.objectCount());
    for (uint32_t t : space.sampleable) texels[w_.mesh.faceObject[space.map.triangle(t)]].push_back(t);
    for (int o = 0; o < appearance_.objectCount(); ++o)
      if (emitter_[o] && !texels[o].empty()) f.candidates.push_back(std::move(texels[o]));
    return f;
  }

  // The uniform batch, then (in the material and emission stages) the focused texels, each set
  // with its own seed stream; every connection traced samples_per_ray times.
  Batch sampleBatch(const TexelSpace& space, uint64_t iteration, RayFootprint footprint, const BatchFocus& focus = {}) const {
    if (c_.sampler != "texture")
      return ImageSpaceSampler(w_.trainingFrames()).sample(c_.seed, iteration, c_.imageRays, *w_.scene, footprint, c_.samplesPerRay);
    const TextureSpaceSampler sampler(*w_.scene, space.map, space.sampleable, w_.vis, w_.trainingFrames());
    Batch b = sampler.sample(c_.seed, iteration, {c_.batchTexels, c_.framesPerTexel, footprint, c_.samplesPerRay});
    auto add = [&](const std::vector<uint32_t>& texels, int count, RayFootprint fp, uint64_t stream) {
      if (texels.empty() || count == 0) return;
      const TextureSpaceSampler focused(*w_.scene, space.map, texels, w_.vis, w_.trainingFrames());
      b.append(focused.sample(hashTuple({c_.seed, stream}), iteration, {count, c_.framesPerTexel, fp, c_.samplesPerRay}));
    };
    add(focus.objects, c_.materialBatchTexels, materialFootprint_, 0x6d6174);
    add(focus.highlights, c_.highlightBatchTexels, materialFootprint_, 0x686c74);
    const int perCandidate = focus.candidates.empty() ? 0 : std::max<int>(1, c_.emissionBatchTexels / static_cast<int>(focus.candidates.size()));
    for (size_t i = 0; i < focus.candidates.size(); ++i) add(focus.candidates[i], perCandidate, footprint, hashTuple({0x656d69, i}));
    return b;
  }

  void runStage(const Stage& st, size_t stageIndex, int firstIteration, const TexelSpace& space, const fs::path& checkpointPath) {
    AdjointSettings settings = settings_;
    settings.mask = st.active;
    // The iteration a settling group's average starts at (never for the others).
    auto averageFrom = [&](ParamKind kind) {
      const bool perObjectMaterial = kind == ParamKind::Roughness || kind == ParamKind::Specular;
      const float fraction = perObjectMaterial ? c_.materialPolyakFraction : c_.polyakFraction;
      return st.settles.active(kind) && fraction > 0
                 ? st.iterations - std::max(1, static_cast<int>(std::lround(fraction * st.iterations)))
                 : st.iterations;
    };
    Progress progress(st.name, static_cast<size_t>(st.iterations));
    progress.advance(static_cast<size_t>(firstIteration));
    FitPhaseTimes times;
    // One buffer per stage, cleared every iteration; curvature only where the albedo steps by it.
    Gradients grads(appearance_, newtonAlbedo() && st.active.active(ParamKind::Albedo));
    const BatchFocus focus = st.active.active(ParamKind::Roughness) ? materialFocus(space)
                             : st.focusEmitters                      ? emissionFocus(space)
                                                                     : BatchFocus{};
    for (int it = firstIteration; it < st.iterations; ++it) {
      const uint64_t iteration = static_cast<uint64_t>(globalIteration_);
      // For the groups settling here: constant, then over the stage's second half linear down to
      // lr_final_fraction. Constant for the others.
      const float half = 0.5f * st.iterations;
      const float settleScale = it < half ? 1.0f : 1.0f - (1.0f - c_.lrFinalFraction) * (it - half) / std::max(1.0f, half);
      FitPhaseTimes now;
      Timer ts;
      const Batch batch = sampleBatch(space, iteration, st.footprint, focus);
      now.sample = ts.seconds();
      stats_.add(batch.stats);
      if (st.pruneAfter)
        for (size_t j = 0; j < batch.rays.size(); ++j)
          observedSum_[batch.object[j]] += luminance(batch.rays[j].reference), ++observedCount_[batch.object[j]];
      Timer tl;
      lights_ = LightSampler(*w_.scene, appearance_, lights_ ? &*lights_ : nullptr);
      now.lights = tl.seconds();
      if (lights_->builtTables() > 0) spdlog::debug("fit: light sampler built the tables of {} objects", lights_->builtTables());
      const GradientResult gr = computeGradients(*w_.scene, appearance_, *lights_, batch.rays, settings, iteration, grads);
      now.primal = gr.times.primal, now.loss = gr.times.loss, now.adjoint = gr.times.adjoint;
      Timer to;
      bool averagesStart = false;
      // Every non-zero albedo gradient is at one of these: the mask and the step cost the batch
      // (listed only in the stages that step the albedo).
      const std::vector<uint32_t> splatted = st.active.active(ParamKind::Albedo) ? grads.splattedAlbedoTexels() : std::vector<uint32_t>{};
      for (ParamGroup& g : paramGroups(appearance_, &grads)) {
        if (!st.active.active(g.kind)) continue;
        maskGradients(g, grads.albedoCurvature, space, splatted);
        const float lrScale = st.settles.active(g.kind) ? settleScale : 1.0f;
        if (g.kind == ParamKind::Albedo && newtonAlbedo()) {
          // No gradient clamp: the step is bounded by maxStep, and a bright outlier in the adjoint
          // sample inflates the curvature as much as the gradient.
          if (newton_.size() != g.values.size()) newton_ = GaussNewtonState(g.values.size());
          GaussNewtonSettings gn;
          gn.damping = c_.albedoDamping * lrScale;
          newton_.stepTexels(g.values, g.grads, grads.albedoCurvature, g.lo, g.hi, gn, splatted);
        } else {
          clampGradients(g.grads, c_.gradientClamp);
          auto [state, inserted] = adam_.try_emplace(g.name(), g.values.size());
          if (state->second.size() != g.values.size()) state->second = AdamState(g.values.size());
          state->second.step(g.values, g.grads, g.lo, g.hi, adamFor(g, lrScale), static_cast<uint32_t>(it + 1));
        }
        const int from = averageFrom(g.kind);
        if (it >= from) polyak_[g.name()].add(g.values);
        averagesStart |= it == from;
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
        const Json memory = memoryBreakdown(space, grads, batch, settings);
        spdlog::log(lightsGrew && !(it == firstIteration || averagesStart) ? spdlog::level::debug : spdlog::level::info,
                    "fit: stage {} holds {:.1f} MiB", st.name, memory["total"].get<double>() / (1 << 20));
        spdlog::debug("fit: bytes by part: {}", memory.dump());
        if (peakMemory_.empty() || memory["total"] > peakMemory_["total"]) peakMemory_ = memory;
      }
      if (hooks_.afterIteration) {
        Timer th;
        const bool go = hooks_.afterIteration(FitIteration{st.name, globalIteration_, fitSeconds(), now, batch.rays, batch.object, *w_.scene,
                                                          *lights_, settings, !grads.albedoCurvature.empty(), appearance_,
                                                          w_.mesh, peakMemory_});
        hookSeconds_ += th.seconds();
        if (!go) {
          if (hooks_.writeFiles) writeCheckpoint(checkpointPath, stageIndex, it + 1, space);
          stopped_ = true;
          return;
        }
      }
      progress.advance();
      const double traceSeconds = gr.times.primal + gr.times.adjoint;
      progress.note(fmt::format("loss {:.3e}, {} rays, {:.2f} Mrays/s", gr.loss, batch.rays.size(),
                                traceSeconds > 0 ? batch.rays.size() / traceSeconds * 1e-6 : 0.0));
      if (hooks_.writeFiles && ((it + 1) % c_.metricsEvery == 0 || it + 1 == st.iterations)) {
        Json line = {{"stage", st.name}, {"iteration", globalIteration_}, {"stage_iteration", it + 1}, {"loss", gr.loss},
                     {"rays", batch.rays.size()}, {"lr_scale", st.settles.bits != 0 ? settleScale : 1.0f}, {"sampler", statsJson(batch.stats)},
                     {"seconds", times.toJson()}};
        if (st.active.active(ParamKind::Roughness))  // the fitted objects' trajectories: how settled they are
          for (int o = 0; o < appearance_.objectCount(); ++o)
            if (highlight_[o]) line["materials"][appearance_.names[o]] = {appearance_.roughness[o], appearance_.specular[o]};
        appendMetrics(line);
      }
      if (hooks_.writeFiles && (it + 1) % c_.checkpointEvery == 0 && it + 1 < st.iterations)
        writeCheckpoint(checkpointPath, stageIndex, it + 1, space);
      if (c_.stopAfterIterations > 0 && globalIteration_ >= c_.stopAfterIterations && it + 1 < st.iterations) {
        if (hooks_.writeFiles) writeCheckpoint(checkpointPath, stageIndex, it + 1, space);
        stopped_ = true;
        return;
      }
    }
    for (ParamGroup& g : paramGroups(appearance_))
      if (st.settles.active(g.kind))
        if (auto p = polyak_.find(g.name()); p != polyak_.end() && p->second.mean.size() == g.values.size())
          std::copy(p->second.mean.begin(), p->second.mean.end(), g.values.begin());
    // Before the boundary checkpoint: a run resumed from it starts the next stage pruned.
    if (st.fillUnobservedAfter) fillUnobservedAlbedo(space);
    if (st.pruneAfter || st.redecideAfter) {
      decideLightSources(space, st.name, st.pruneAfter);
      lights_.reset();  // no table for the candidates that stopped being lights
    }
    if (hooks_.writeFiles) writeCheckpoint(checkpointPath, stageIndex + 1, 0, space);
    spdlog::info("fit: stage {} done: {} iterations, loss {:.4e}; per iteration: sample {:.1f} ms, primal {:.1f} ms, adjoint {:.1f} ms, optimiser {:.1f} ms",
                 st.name, st.iterations - firstIteration, lastLoss_, 1e3 * times.sample / std::max(1, st.iterations - firstIteration),
                 1e3 * times.primal / std::max(1, st.iterations - firstIteration),
                 1e3 * times.adjoint / std::max(1, st.iterations - firstIteration),
                 1e3 * times.optimiser / std::max(1, st.iterations - firstIteration));
  }

  // An object no kept frame sees is not a light-source candidate: nothing of its own radiance is
  // observed, so its emission is constrained only by the light it throws on other surfaces, which
  // trades off against their albedo. Fitted anyway, the 16-frame test room's never-seen painting
  // came out a blue emitter in one seed of three, and relighting with the ceiling lights off lost 5 dB.
  void excludeUnseenEmitters(const TexelSpace& space) {
    std::vector<uint8_t> seen(appearance_.objectCount(), 0);
    for (uint32_t t : space.sampleable) seen[w_.mesh.faceObject[space.map.triangle(t)]] = 1;
    for (int o = 0; o < appearance_.objectCount(); ++o)
      if (!seen[o]) {
        emitter_[o] = 0;
        spdlog::info("fit: object {} ({}) is seen by no frame: not a light-source candidate", o, appearance_.names[o]);
      }
  }

  // A light source's albedo is held at 0 (light_albedo_zero) once the lights are decided.
  bool albedoHeld(int object) const { return c_.lightAlbedoZero && lightsDecided() && emitter_[object]; }
  bool lightsDecided() const { return !c_.lights.empty() || !lightDecisions_.empty(); }

  // Light sources show their radiance as emission alone (light_albedo_zero): albedo 0 on their texels.
  void zeroLightAlbedo(const TexelSpace& space) {
    if (!c_.lightAlbedoZero) return;
    for (size_t t = 0; t < space.map.texelCount(); ++t)
      if (space.map.valid(t) && emitter_[w_.mesh.faceObject[space.map.triangle(t)]])
        std::fill_n(appearance_.albedo.rgb.begin() + 3 * static_cast<ptrdiff_t>(t), 3, 0.0f);
  }

  // The `lights` hint: exactly the objects it names are light-source candidates, and they stay
  // lights (no decision is taken).
  void applyLightsHint() {
    if (c_.lights.empty()) return;
    std::vector<uint8_t> hinted(appearance_.objectCount(), 0);
    for (const std::string& name : c_.lights) {
      const auto it = std::find(appearance_.names.begin(), appearance_.names.end(), name);
      if (it == appearance_.names.end()) fail("fit config: 'lights' names '{}', which is no object of {}", name, w_.dir.string());
      hinted[it - appearance_.names.begin()] = 1;
    }
    for (int o = 0; o < appearance_.objectCount(); ++o) {
      if (hinted[o] && !emitter_[o]) spdlog::warn("fit: object {} ({}) is named a light but no frame sees it: its emission stays 0", o, appearance_.names[o]);
      emitter_[o] = emitter_[o] && hinted[o];
    }
  }

  // The light sources, decided from the evidence of their own pixels (light_evidence.h). First
  // (after the emission stage): among the emission stage's candidates, with the albedo still its
  // init; again after the first albedo stage: among every object with texels, under the fitted
  // albedo. An object that becomes a light starts from the emission its evidence implies, one that
  // stops goes to 0, and either change makes the emission_refit stage run. Objects a mirror
  // explains better than an emission (out of model) leave the emission and the albedo for good.
  void decideLightSources(const TexelSpace& space, const std::string& after, bool first) {
    if (!c_.lights.empty()) return;  // the user named them
    if (c_.lightTest == "radiance_fraction") {
      if (first) prune();
      return;
    }
    const int objects = appearance_.objectCount();
    std::vector<std::vector<uint32_t>> texels(objects);
    for (uint32_t t : space.sampleable) texels[w_.mesh.faceObject[space.map.triangle(t)]].push_back(t);
    std::vector<uint8_t> candidate(objects, 0);
    for (int o = 0; o < objects; ++o) candidate[o] = !texels[o].empty() && !outOfModel_[o] && (first ? emitter_[o] != 0 : true);
    // Each candidate's own texels, the same number for each, through their centres (point rays).
    const uint64_t stream = hashTuple({c_.seed, 0x6c69676874ULL, lightDecisions_.size()});
    Batch batch;
    for (int o = 0; o < objects; ++o) {
      if (!candidate[o]) continue;
      const TextureSpaceSampler own(*w_.scene, space.map, texels[o], w_.vis, w_.trainingFrames());
      batch.append(own.sample(hashTuple({stream, static_cast<uint64_t>(o)}), 0,
                              {c_.lightEvidenceTexels, c_.framesPerTexel, RayFootprint::Point, 1}));
    }
    // Each ray's camera, found by its origin (the sampler's rays start at the camera).
    std::map<std::array<float, 3>, const Camera*> byPosition;
    for (uint32_t k : w_.kept) {
      const Vec3& p = w_.frames[k].camera.position;
      byPosition.emplace(std::array<float, 3>{p.x(), p.y(), p.z()}, &w_.frames[k].camera);
    }
    std::vector<const Camera*> cameras(batch.rays.size());
    for (size_t j = 0; j < batch.rays.size(); ++j) {
      const Vec3& o = batch.rays[j].origin;
      const auto it = byPosition.find({o.x(), o.y(), o.z()});
      cameras[j] = it != byPosition.end() ? it->second : nullptr;
    }
    const LightSampler lights(*w_.scene, appearance_);
    std::vector<LightEvidence> evidence =
        gatherLightEvidence(*w_.scene, w_.mesh, appearance_, lights, batch.rays, batch.object, settings_.path, stream, &cameras);
    const LightTestSettings test{c_.lightMinUnexplained, c_.lightSignificance, c_.pruneFraction, c_.lightMinContrast};
    const std::vector<LightDecision> decisions = decideLights(evidence, candidate, test);
    // Under-lit surfaces are reported at the last decision only: before the albedo is fitted, the
    // init darkens the light every surface receives (the White Room: 12 under-lit reflectors after
    // the emission stage, none after the first albedo stage).
    const bool last = !first || !c_.lightRedecide;
    std::vector<uint8_t> dropped(objects, 0);
    bool changed = false;
    for (int o = 0; o < objects; ++o) {
      if (!candidate[o]) continue;
      const LightDecision& d = decisions[o];
      const bool light = d.verdict == LightVerdict::Light;
      spdlog::info("fit: after {}: object {} ({}) is {}: {}", after, o, appearance_.names[o], lightVerdictName(d.verdict), d.why);
      if (const UnderLit u = underLit(evidence[o], test); last && u.underLit && d.verdict == LightVerdict::Reflector)
        spdlog::warn("fit: after {}: object {} ({}) is under-lit: {:.3g} of its radiance no light in view explains; the missing light "
                     "lands around ({:.2f}, {:.2f}, {:.2f}) and comes from direction ({:.2f}, {:.2f}, {:.2f}) (a light seen only from "
                     "behind, outside the frames or under a shade?)",
                     after, o, appearance_.names[o], u.missing, u.centre[0], u.centre[1], u.centre[2], u.from[0], u.from[1], u.from[2]);
      if (d.verdict == LightVerdict::OutOfModel) outOfModel_[o] = 1;
      emitter_[o] = light;
      if (!light) {
        dropped[o] = !first && appearance_.isEmissive(o);
        appearance_.emission[o] = Color::Zero();
      } else {
        // A light's emission is set when it becomes one (and, with light_albedo_zero, at the
        // first decision, where its albedo goes to 0); a re-decision that agrees changes nothing.
        const bool wasEmitting = appearance_.isEmissive(o);
        if (c_.lightAlbedoZero && (first || !wasEmitting)) appearance_.emission[o] = evidence[o].meanObservedColor();
        else if (!wasEmitting) appearance_.emission[o] = evidence[o].emissionEstimate();
        changed |= !first && !wasEmitting;
      }
    }
    changed |= std::count(dropped.begin(), dropped.end(), 1) > 0;
    zeroLightAlbedo(space);
    if (changed) {
      refitEmission_ = 1;
      restartAlbedo(space, evidence, dropped);
    }
    lightDecisions_.push_back({{"after", after}, {"objects", lightDecisionsJson(evidence, decisions, appearance_.names, test, last)}});
  }

  // Texels no frame saw are never updated; they light the rest of the scene all the same (a
  // capture that faces one way leaves most of a room unseen: 78% of the White Room's texels). They
  // take their object's mean albedo over its observed texels, or 0.5 on an object no frame saw,
  // instead of the init's radiance-scaled guess (an unseen wall's mean radiance x the white-point
  // scale: 0.07 for a wall of albedo 0.6 there, which darkens the light every surface receives).
  void fillUnobservedAlbedo(const TexelSpace& space) {
    const int objects = appearance_.objectCount();
    std::vector<Eigen::Array4d> mean(objects, Eigen::Array4d::Zero());
    const std::vector<float>& a = appearance_.albedo.rgb;
    for (uint32_t t : space.sampleable)
      mean[w_.mesh.faceObject[space.map.triangle(t)]] += Eigen::Array4d(a[3 * t], a[3 * t + 1], a[3 * t + 2], 1.0);
    size_t filled = 0;
    for (size_t t = 0; t < space.map.texelCount(); ++t) {
      if (!space.map.valid(t) || space.updatable[t] || outOfModel_[w_.mesh.faceObject[space.map.triangle(t)]]) continue;
      const Eigen::Array4d& m = mean[w_.mesh.faceObject[space.map.triangle(t)]];
      const Color fill = m[3] > 0 ? Color((m.head<3>() / m[3]).cast<float>()) : Color::Constant(0.5f);
      for (int c = 0; c < 3; ++c) appearance_.albedo.rgb[3 * t + c] = fill[c];
      ++filled;
    }
    spdlog::debug("fit: {} unobserved texels take their object's mean albedo", filled);
  }

  // The lights changed, so every albedo was fitted under the wrong light: the running fits start
  // over (their averages hold residuals of the old lights), as does the emission's Adam state, and an object that stopped being a
  // light, whose albedo had collapsed while its emission made up its radiance, is rescaled to the
  // albedo its evidence implies (what it shows over what albedo 1 returns).
  void restartAlbedo(const TexelSpace& space, const std::vector<LightEvidence>& evidence, const std::vector<uint8_t>& dropped) {
    const int objects = appearance_.objectCount();
    std::vector<Eigen::Array3d> sum(objects, Eigen::Array3d::Zero());
    std::vector<size_t> count(objects, 0);
    for (uint32_t t : space.sampleable) {
      const int o = w_.mesh.faceObject[space.map.triangle(t)];
      if (!dropped[o]) continue;
      sum[o] += Eigen::Array3d(appearance_.albedo.rgb[3 * t], appearance_.albedo.rgb[3 * t + 1], appearance_.albedo.rgb[3 * t + 2]);
      ++count[o];
    }
    // Each channel scaled so that its mean is the estimate; set to it where the albedo is ~0 (held
    // at 0 while the object was a light).
    std::vector<Color> target(objects, Color::Zero()), scale(objects, Color::Zero());
    for (int o = 0; o < objects; ++o)
      if (dropped[o] && count[o] > 0) {
        target[o] = evidence[o].albedoEstimate();
        for (int c = 0; c < 3; ++c) scale[o][c] = sum[o][c] > 1e-3 * count[o] ? static_cast<float>(target[o][c] * count[o] / sum[o][c]) : 0.0f;
        spdlog::info("fit: object {} ({}) is no light: its albedo restarts at {:.3g} {:.3g} {:.3g}", o, appearance_.names[o],
                     target[o][0], target[o][1], target[o][2]);
      }
    for (size_t t = 0; t < space.map.texelCount(); ++t) {
      if (!space.map.valid(t)) continue;
      const int o = w_.mesh.faceObject[space.map.triangle(t)];
      if (!dropped[o] || count[o] == 0) continue;
      for (int c = 0; c < 3; ++c) {
        float& a = appearance_.albedo.rgb[3 * t + c];
        a = std::clamp(scale[o][c] > 0 ? a * scale[o][c] : target[o][c], 0.0f, 1.0f);
      }
    }
    newton_ = GaussNewtonState();
    adam_.erase("albedo");
    polyak_.erase("albedo");
    adam_.erase("emission");  // the lights' emissions were set anew
  }

  // light_test radiance_fraction: light sources are the objects whose own emission explains most of how they look (at least
  // emitter_radiance_fraction of their mean observed radiance) and that carry at least
  // prune_fraction of the total emitted power. The rest go to 0 and stay frozen. The radiance test
  // matters because during this stage the albedo is the median radiance, darker than the true
  // albedo by the irradiance factor, so lit walls make up for it with a weak emission of their own.
  void prune() {
    std::vector<double> area(appearance_.objectCount(), 0.0);
    for (size_t f = 0; f < w_.mesh.triangles.size(); ++f) {
      const auto& t = w_.mesh.triangles[f];
      area[w_.mesh.faceObject[f]] +=
          0.5 * (w_.mesh.positions[t[1]] - w_.mesh.positions[t[0]]).cross(w_.mesh.positions[t[2]] - w_.mesh.positions[t[0]]).norm();
    }
    std::vector<double> power(appearance_.objectCount());
    double totalPower = 0;
    for (int o = 0; o < appearance_.objectCount(); ++o) totalPower += power[o] = luminance(appearance_.emission[o]) * area[o];
    for (int o = 0; o < appearance_.objectCount(); ++o) {
      const double observed = observedCount_[o] ? observedSum_[o] / observedCount_[o] : 0.0;
      emitter_[o] = emitter_[o] && totalPower > 0 && power[o] >= c_.pruneFraction * totalPower &&
                    luminance(appearance_.emission[o]) >= c_.emitterRadianceFraction * observed;
      if (power[o] >= c_.pruneFraction * totalPower && !emitter_[o])
        spdlog::info("fit: object {} ({}) emits {:.3g} but looks {:.3g}: lit, not a light source", o, appearance_.names[o],
                     luminance(appearance_.emission[o]), observed);
      if (!emitter_[o]) appearance_.emission[o] = Color::Zero();
      else spdlog::info("fit: object {} ({}) is a light source: emission {:.3g} {:.3g} {:.3g}, {:.1f}% of the power", o,
                        appearance_.names[o], appearance_.emission[o][0], appearance_.emission[o][1], appearance_.emission[o][2],
                        100 * power[o] / totalPower);
    }
  }

  // Whether a connection sees a light reflected: the mirror direction about the geometric normal,
  // or one of four directions 10 degrees around it (a glossy lobe's width), reaches the front of
  // an emitter. -1: the reference is masked or the ray hits nothing.
  int8_t seesLightReflected(const BatchRay& r) const {
    if (!(r.reference.minCoeff() >= 0)) return -1;
    const auto hit = w_.scene->intersect(r.origin, r.dir);
    if (!hit) return -1;
    int8_t seen = 0;
    forEachMirrorDirection(*hit, r.dir, [&](const Vec3& d) {
      const auto light = w_.scene->intersect(Scene::offsetOrigin(*hit, d), d);
      if (light && emitter_[light->object] && appearance_.isEmissive(light->object) && light->ng.dot(d) < 0) seen = 1;
      return seen == 0;
    });
    return seen;
  }

  // Which objects the frames show a highlight on. Probe connections either see a light reflected
  // or not (seesLightReflected); a highlight is what that does to the pixel: for each texel with
  // connections of both kinds, contrast = mean radiance seeing a light / mean radiance not - 1
  // (the same texel from other frames, so albedo and irradiance cancel). Roughness and specular
  // are fitted on objects whose mean contrast, less two standard errors, reaches
  // highlight_min_contrast over at least highlight_min_pairs texels; elsewhere nothing in the data
  // constrains them (a rough wall reflecting a lamp at a grazing angle is no brighter for it), so
  // they keep their init and are reported unconstrained.
  void decideHighlights(const TexelSpace& space) {
    const int objects = appearance_.objectCount();
    HighlightEvidence evidence(objects);
    for (uint64_t probe = 0; probe < kHighlightProbeBatches; ++probe) {
      const Batch batch = sampleBatch(space, (uint64_t{1} << 40) + probe, footprint_);
      std::vector<int8_t> sawLight(batch.rays.size(), -1);
      std::vector<float> lum(batch.rays.size(), 0.0f);
      tbb::parallel_for(size_t{0}, batch.rays.size(), [&](size_t j) {
        sawLight[j] = seesLightReflected(batch.rays[j]);
        if (sawLight[j] >= 0) lum[j] = luminance(batch.rays[j].reference);
      });
      evidence.addBatch(batch.slot, batch.object, lum, sawLight);
    }
    for (int o = 0; o < objects; ++o) {
      highlightPairs_[o] = evidence.texels(o), highlightContrast_[o] = evidence.contrast(o);
      highlight_[o] = !emitter_[o] && evidence.observed(o, c_.highlightMinPairs, c_.highlightMinContrast);
      spdlog::info("fit: object {} ({}): {} texels seen with and without a light reflected, {:+.1f}% +- {:.1f}% brighter with it -> "
                   "roughness/specular {}",
                   o, appearance_.names[o], evidence.texels(o), 100 * evidence.contrast(o), 100 * evidence.standardError(o),
                   highlight_[o] ? "fitted" : "unconstrained (kept at init)");
    }
  }

  double fitSeconds() const { return total_.seconds() - hookSeconds_; }

  // Bytes the fit holds, by part, once a stage's buffers are allocated. The frame cache is a
  // mapping of frames.bin: only the pages the sampler touches become resident.
  Json memoryBreakdown(const TexelSpace& space, Gradients& grads, const Batch& batch, const AdjointSettings& settings) {
    auto floats = [](size_t n) { return static_cast<double>(n * sizeof(float)); };
    double parameters = 0, gradients = floats(grads.albedoCurvature.size()) + grads.bookkeepingBytes(), optimiser = 0, averages = 0;
    for (ParamGroup& g : paramGroups(appearance_, &grads))
      parameters += floats(g.values.size()), gradients += floats(g.grads.size());
    for (const auto& [name, a] : adam_) optimiser += floats(a.m.size() + a.v.size()) + a.steps.size() * sizeof(uint16_t);
    optimiser += floats(newton_.numerator.size() + newton_.curvature.size()) + newton_.steps.size() * sizeof(uint16_t);
    for (const auto& [name, p] : polyak_) averages += floats(p.mean.size());
    const double texels = space.map.bytes() + space.sampleable.size() * sizeof(uint32_t) + space.updatable.size();
    const TriangleMesh& m = w_.mesh;  // its arrays; Embree's BVH and the shading records not counted
    const double mesh = (m.positions.size() + m.normals.size()) * sizeof(Vec3) + m.uvs.size() * sizeof(Vec2) +
                        m.triangles.size() * (sizeof(Eigen::Vector3i) + sizeof(int32_t));
    const double batchBytes = batch.rays.size() * (sizeof(BatchRay) + sizeof(uint32_t) + sizeof(int) + 3 * sizeof(Color));
    const double records = double(threadCount()) * adjointRecordBytesPerThread(settings.path.maxDepth);
    Json j = {{"parameters", parameters}, {"gradients", gradients}, {"optimiser_state", optimiser}, {"averages", averages},
              {"texel_map", texels}, {"mesh", mesh}, {"visibility_index", static_cast<double>(w_.vis.bytes())},
              {"frame_cache_mapped", static_cast<double>(w_.store->mappedBytes())}, {"batch", batchBytes},
              {"path_records", records}, {"gradient_logs", static_cast<double>(grads.logBytes())},
              {"light_sampler", lights_ ? static_cast<double>(lights_->bytes()) : 0.0}};
    double total = 0;
    for (const auto& [k, v] : j.items())
      if (k != "frame_cache_mapped") total += v.get<double>();
    j["total"] = total;  // without the frame cache, which is file-backed and mostly not resident
    return j;
  }

  static Json statsJson(const SamplerStats& s) {
    return {{"slots", s.slots}, {"candidates", s.candidates}, {"not_seen", s.notSeen},
            {"first_hit_elsewhere", s.firstHitElsewhere}, {"masked", s.masked}, {"rays", s.rays}};
  }

  void appendMetrics(const Json& j) {
    std::ofstream out(w_.dir / "metrics.jsonl", std::ios::app);
    out << j.dump() << '\n';
  }

  void writeCheckpoint(const fs::path& path, size_t stage, int iteration, const TexelSpace& space) {
    Checkpoint ck;
    ck.meta = {{"version", kCheckpointVersion}, {"config", c_.toJson()}, {"stage", stage}, {"iteration", iteration},
               {"global_iteration", globalIteration_}, {"resolution", space.resolution},
               {"emission_textures", !appearance_.emissionTextures.empty()}, {"loss", lastLoss_},
               {"emission_texture_resolution", appearance_.emissionTextures.empty() ? 0 : appearance_.emissionTextures[0].fullWidth}};
    for (ParamGroup& g : paramGroups(appearance_)) ck.put(g.name() + ".values", std::span<const float>(g.values));
    for (const auto& [name, s] : adam_) {
      ck.put(name + ".m", s.m);
      ck.put(name + ".v", s.v);
      ck.put(name + ".steps", s.steps);
    }
    for (const auto& [name, p] : polyak_) {
      ck.put(name + ".mean", p.mean);
      ck.put(name + ".count", std::vector<uint32_t>{p.count});
    }
    if (newton_.size() > 0) {
      ck.put("albedo.numerator", newton_.numerator);
      ck.put("albedo.curvature", newton_.curvature);
      ck.put("albedo.curvature_steps", newton_.steps);
    }
    ck.meta["light_decisions"] = lightDecisions_;
    ck.put("emitter", emitter_);
    ck.put("out_of_model", outOfModel_);
    ck.put("refit_emission", std::vector<uint8_t>{refitEmission_});
    ck.put("highlight", highlight_);
    ck.put("highlight_pairs", highlightPairs_);
    ck.put("highlight_contrast", highlightContrast_);
    ck.put("observed.sum", observedSum_);
    ck.put("observed.count", observedCount_);
    ck.write(path);
  }

  void restore(const Checkpoint& ck) {
    for (ParamGroup& g : paramGroups(appearance_)) ck.get(g.name() + ".values", g.values);
    for (ParamGroup& g : paramGroups(appearance_)) {
      if (!ck.has(g.name() + ".m")) continue;
      AdamState s(g.values.size());
      ck.get(g.name() + ".m", s.m);
      ck.get(g.name() + ".v", s.v);
      ck.get(g.name() + ".steps", s.steps);
      adam_[g.name()] = std::move(s);
    }
    // Averages independently of Adam state: the albedo has none under the Gauss-Newton step.
    for (ParamGroup& g : paramGroups(appearance_)) {
      if (!ck.has(g.name() + ".mean")) continue;
      PolyakAverage& p = polyak_[g.name()];
      p.mean.resize(g.values.size());
      ck.get(g.name() + ".mean", p.mean);
      std::vector<uint32_t> count(1);
      ck.get(g.name() + ".count", count);
      p.count = count[0];
    }
    if (newtonAlbedo() && ck.has("albedo.curvature")) {
      newton_ = GaussNewtonState(appearance_.albedo.rgb.size());
      ck.get("albedo.numerator", newton_.numerator);
      ck.get("albedo.curvature", newton_.curvature);
      ck.get("albedo.curvature_steps", newton_.steps);
    }
    lightDecisions_ = ck.meta.value("light_decisions", Json::array());
    ck.get("emitter", emitter_);
    ck.get("out_of_model", outOfModel_);
    std::vector<uint8_t> refit(1);
    ck.get("refit_emission", refit);
    refitEmission_ = refit[0];
    ck.get("highlight", highlight_);
    ck.get("highlight_pairs", highlightPairs_);
    ck.get("highlight_contrast", highlightContrast_);
    ck.get("observed.sum", observedSum_);
    ck.get("observed.count", observedCount_);
    lastLoss_ = ck.meta.value("loss", 0.0);
  }

  fs::path writeResult(const TexelSpace& space) {
    const fs::path result = w_.dir / "result", staging = w_.dir / "result.partial";
    fs::remove_all(staging);
    fs::create_directories(staging);
    SceneDescription desc{w_.dir / "atlas_mesh.ply", w_.mesh, appearance_};
    saveSceneFile(staging / "scene.json", desc);
    Image albedo(space.resolution, space.resolution);
    albedo.rgb = appearance_.albedo.rgb;
    writePng(staging / "albedo.png", albedo);
    Json materials = Json::array();
    std::vector<size_t> observed(appearance_.objectCount(), 0), total(appearance_.objectCount(), 0);
    for (size_t t = 0; t < space.map.texelCount(); ++t)
      if (space.map.covered(t)) {
        const int o = w_.mesh.faceObject[space.map.triangle(t)];
        ++total[o];
        observed[o] += space.updatable[t];
      }
    for (int o = 0; o < appearance_.objectCount(); ++o) {
      const Color e = appearance_.meanEmission(o);
      materials.push_back({{"id", o}, {"name", appearance_.names[o]}, {"roughness", appearance_.roughness[o]},
                           {"specular", appearance_.specular[o]}, {"emission", {e[0], e[1], e[2]}},
                           {"is_emitter", appearance_.isEmissive(o)}, {"out_of_model", outOfModel_[o] != 0},
                           {"highlight_observed", highlight_[o] != 0},
                           {"highlight_texels", highlightPairs_[o]}, {"highlight_contrast", highlightContrast_[o]},
                           {"observed_texel_fraction", total[o] ? double(observed[o]) / total[o] : 0.0}});
    }
    Json summary = {{"objects", materials}, {"albedo_resolution", space.resolution}, {"iterations", globalIteration_},
                    {"final_loss", lastLoss_}, {"sampler", statsJson(stats_)}, {"config", c_.toJson()},
                    {"peak_rss_mib", peakRssMiB()}, {"memory_bytes", peakMemory_}};
    writeJson(staging / "materials.json", summary);
    writeJson(staging / "lights.json", {{"light_test", c_.lightTest}, {"hint", c_.lights}, {"decisions", lightDecisions_}});
    fs::remove_all(result);
    fs::rename(staging, result);
    spdlog::info("fit: result in {}", result.string());
    return result;
  }

  FitConfig c_;
  FitHooks hooks_;
  Timer total_;
  double hookSeconds_ = 0;
  Json peakMemory_;
  Workspace w_;
  Appearance appearance_;
  AdjointSettings settings_;
  std::vector<uint8_t> emitter_, highlight_;
  std::vector<uint8_t> outOfModel_;  // per object: excluded from emission and albedo (light_evidence.h)
  uint8_t refitEmission_ = 0;        // the re-decision changed the light sources: run emission_refit
  Json lightDecisions_ = Json::array();  // each decision's evidence (result/lights.json)
  const RayFootprint footprint_ = parseRayFootprint(c_.rayFootprint);
  const RayFootprint materialFootprint_ = parseRayFootprint(c_.materialFootprint);
  std::vector<uint64_t> highlightPairs_;  // per object: texels compared with and without a light reflected
  std::vector<double> highlightContrast_;  // their mean contrast
  std::vector<double> observedSum_;      // per object, luminance of the references seen in the emission stage
  std::vector<uint64_t> observedCount_;
  std::map<std::string, AdamState> adam_;
  GaussNewtonState newton_;  // the albedo's, with albedo_step gauss-newton
  std::map<std::string, PolyakAverage> polyak_;
  SamplerStats stats_;
  std::optional<LightSampler> lights_;  // by the current emission; each iteration's shares the last's tables
  size_t lightSamplerBytesPeak_ = 0;  // the most lights_->bytes() has been
  float radianceScale_ = 1e-6f;
  int finalRes_ = 0;
  int globalIteration_ = 0;
  bool stopped_ = false;
  double lastLoss_ = 0;
};

}  // namespace

FitPhaseTimes& FitPhaseTimes::operator+=(const FitPhaseTimes& o) {
  sample += o.sample, lights += o.lights, primal += o.primal, loss += o.loss, adjoint += o.adjoint, optimiser += o.optimiser;
  return *this;
}

Json FitPhaseTimes::toJson() const {
  return {{"sample", sample}, {"lights", lights}, {"primal", primal}, {"loss", loss}, {"adjoint", adjoint}, {"optimiser", optimiser}};
}

FitSummary runFit(const fs::path& work, const FitConfig& config, bool resume, const FitHooks& hooks) {
  validate(config, "fit config");
  Fit fit(work, config, hooks);
  return fit.run(resume);
}

}  // namespace relume
