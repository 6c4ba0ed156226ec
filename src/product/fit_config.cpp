#include "product/fit_config.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <set>
#include <variant>

#include "core/error.h"

namespace relume {
namespace {

using ConfigField = std::variant<int*, float*, bool*, uint64_t*, std::vector<std::string>*, SamplerKind*, AlbedoStep*,
                                 LightTest*, RayFootprint*, GradientMode*, EmitterGradients*, Pairing*, FrameGainMode*,
                                 AlbedoSmoothing*, RefinePoses*, UnalignedFrames*>;

// The keys, in the order the reference lists them.
template <typename Fn>
void forEachConfigKey(FitConfig& c, Fn&& fn) {
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
  fn("albedo_standard_error", ConfigField(&c.albedoStandardError));
  fn("albedo_smoothing", ConfigField(&c.albedoSmoothing));
  fn("albedo_smoothing_radius", ConfigField(&c.albedoSmoothingRadius));
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
  fn("stop_on_convergence", ConfigField(&c.stopOnConvergence));
  fn("convergence_ratio", ConfigField(&c.convergenceRatio));
  fn("convergence_standard_error", ConfigField(&c.convergenceStandardError));
  fn("convergence_check_passes", ConfigField(&c.convergenceCheckPasses));
  fn("max_resolution", ConfigField(&c.maxResolution));
  fn("time_budget", ConfigField(&c.timeBudget));
  fn("memory_budget_mib", ConfigField(&c.memoryBudgetMib));
  fn("light_test", ConfigField(&c.lightTest));
  fn("light_min_unexplained", ConfigField(&c.lightMinUnexplained));
  fn("light_significance", ConfigField(&c.lightSignificance));
  fn("light_min_contrast", ConfigField(&c.lightMinContrast));
  fn("light_saturated_floor", ConfigField(&c.lightSaturatedFloor));
  fn("light_evidence_texels", ConfigField(&c.lightEvidenceTexels));
  fn("light_redecide", ConfigField(&c.lightRedecide));
  fn("clipped_light_scale", ConfigField(&c.clippedLightScale));
  fn("clipped_scale_shown_radiance", ConfigField(&c.clippedScaleShownRadiance));
  fn("clipped_scale_paths", ConfigField(&c.clippedScalePaths));
  fn("clipped_scale_material_choice", ConfigField(&c.clippedScaleMaterialChoice));
  fn("clipped_scale_albedo_ceiling", ConfigField(&c.clippedScaleAlbedoCeiling));
  fn("clipped_light_silhouette_colour", ConfigField(&c.clippedLightSilhouetteColour));
  fn("emission_refit_iterations", ConfigField(&c.emissionRefitIterations));
  fn("lights", ConfigField(&c.lights));
  fn("light_albedo_zero", ConfigField(&c.lightAlbedoZero));
  fn("light_unclipped_emission", ConfigField(&c.lightUnclippedEmission));
  fn("prune_fraction", ConfigField(&c.pruneFraction));
  fn("emitter_radiance_fraction", ConfigField(&c.emitterRadianceFraction));
  fn("highlight_min_pairs", ConfigField(&c.highlightMinPairs));
  fn("highlight_min_contrast", ConfigField(&c.highlightMinContrast));
  fn("highlight_absence", ConfigField(&c.highlightAbsence));
  fn("drop_disagreeing", ConfigField(&c.dropDisagreeing));
  fn("emitter_parameterisation", ConfigField(&c.emitterParameterisation));
  fn("median_init", ConfigField(&c.medianInit));
  fn("init_white_point", ConfigField(&c.initWhitePoint));
  fn("frame_gains", ConfigField(&c.frameGains));
  fn("gain_reference_frame", ConfigField(&c.gainReferenceFrame));
  fn("gain_memory", ConfigField(&c.gainMemory));
  fn("gain_refine", ConfigField(&c.gainRefine));
  fn("refine_poses", ConfigField(&c.refinePoses));
  fn("pose_render_spp", ConfigField(&c.poseRenderSpp));
  fn("pose_image_width", ConfigField(&c.poseImageWidth));
  fn("pose_pyramid_levels", ConfigField(&c.posePyramidLevels));
  fn("unaligned_frames", ConfigField(&c.unalignedFrames));
  fn("coarse_to_fine", ConfigField(&c.coarseToFine));
  fn("emission_textures", ConfigField(&c.emissionTextures));
  fn("emission_texture_resolution", ConfigField(&c.emissionTextureResolution));
  fn("seed", ConfigField(&c.seed));
  fn("stop_after_iterations", ConfigField(&c.stopAfterIterations));
  fn("checkpoint_every", ConfigField(&c.checkpointEvery));
  fn("metrics_every", ConfigField(&c.metricsEvery));
}

float finiteFloat(const Json& v, const std::string& where, const char* key) {
  const float f = static_cast<float>(v.get<double>());
  if (!std::isfinite(f)) fail("{}: '{}' is {}, not finite in float", where, key, v.dump());
  return f;
}

}  // namespace

void FitConfig::validate(const std::string& where) const {
  const FitConfig& c = *this;
  auto need = [&](bool ok, const char* what) {
    if (!ok) fail("{}: {}", where, what);
  };
  need(c.batchTexels >= 1 && c.batchTexels <= (1 << 24), "batch_texels must be in [1, 2^24]");
  need(c.framesPerTexel >= 1 && c.framesPerTexel <= 64, "frames_per_texel must be in [1, 64]");
  need(c.materialBatchTexels >= 0 && c.materialBatchTexels <= (1 << 24), "material_batch_texels must be in [0, 2^24]");
  need(c.highlightBatchTexels >= 0 && c.highlightBatchTexels <= (1 << 24),
       "highlight_batch_texels must be in [0, 2^24]");
  need(c.emissionBatchTexels >= 0 && c.emissionBatchTexels <= (1 << 24), "emission_batch_texels must be in [0, 2^24]");
  need(c.imageRays >= 1 && c.imageRays <= (1 << 24), "image_rays must be in [1, 2^24]");
  need(c.samplesPerRay >= 1 && c.samplesPerRay <= 64, "samples_per_ray must be in [1, 64]");
  need(c.maxDepth >= 0 && c.maxDepth <= 64, "max_depth must be in [0, 64]");
  need(c.rouletteDepth >= 1 && c.rouletteDepth <= 64, "roulette_depth must be in [1, 64]");
  // The Gauss-Newton step models a texel's pixels as linear in the albedo at their first vertex;
  // `full` gradients add the albedo's terms at deeper vertices, which that curvature does not
  // hold (docs/design/fit.md).
  need(c.albedoStep != AlbedoStep::GaussNewton || c.gradients == GradientMode::Direct,
       "gradients full needs albedo_step adam");
  need(c.albedoSmoothing == AlbedoSmoothing::None || c.albedoStandardError,
       "albedo_smoothing needs albedo_standard_error (or set it to none)");
  need(c.albedoSmoothingRadius >= 1 && c.albedoSmoothingRadius <= 8, "albedo_smoothing_radius must be in [1, 8]");
  need(std::isfinite(c.albedoDamping) && c.albedoDamping > 0 && c.albedoDamping <= 1,
       "albedo_damping must be in (0, 1]");
  need(c.lrFinalFraction > 0 && c.lrFinalFraction <= 1, "lr_final_fraction must be in (0, 1]");
  for (float lr : {c.lrAlbedo, c.lrRoughness, c.lrSpecular, c.lrEmission, c.lrEmissionTexture})
    need(std::isfinite(lr) && lr > 0 && lr <= 10, "learning rates must be in (0, 10]");
  need(std::isfinite(c.emissionFloor) && c.emissionFloor > 0 && c.emissionFloor <= 1,
       "emission_floor must be in (0, 1]");
  need(std::isfinite(c.gradientClamp) && c.gradientClamp >= 0, "gradient_clamp must be >= 0 (0 = off)");
  need(c.polyakFraction >= 0 && c.polyakFraction <= 1, "polyak_fraction must be in [0, 1]");
  need(c.materialPolyakFraction >= 0 && c.materialPolyakFraction <= 1, "material_polyak_fraction must be in [0, 1]");
  need(c.emissionIterations >= 0 && c.materialIterations >= 0 && c.emissionTextureIterations >= 0 &&
           c.maxStageIterations >= 1,
       "stage lengths must be >= 0 (max_stage_iterations >= 1)");
  need(std::isfinite(c.albedoPasses) && c.albedoPasses > 0 && c.albedoPasses <= 1e4,
       "albedo_passes must be in (0, 1e4]");
  need(std::isfinite(c.convergenceRatio) && c.convergenceRatio > 0 && c.convergenceRatio <= 1e3,
       "convergence_ratio must be in (0, 1e3]");
  need(std::isfinite(c.convergenceStandardError) && c.convergenceStandardError > 0 && c.convergenceStandardError <= 1,
       "convergence_standard_error must be in (0, 1]");
  need(std::isfinite(c.convergenceCheckPasses) && c.convergenceCheckPasses > 0 && c.convergenceCheckPasses <= 100,
       "convergence_check_passes must be in (0, 100]");
  // The movement is measured on the Gauss-Newton step's standard errors.
  need(!c.stopOnConvergence || (c.albedoStep == AlbedoStep::GaussNewton && c.albedoStandardError),
       "stop_on_convergence needs albedo_step gauss-newton and albedo_standard_error");
  need(c.maxResolution >= 0, "max_resolution must be >= 0");
  need(std::isfinite(c.timeBudget) && c.timeBudget >= 0 && c.timeBudget <= 1e7,
       "time_budget must be in [0, 1e7] seconds (0 = the fixed schedule)");
  need(std::isfinite(c.memoryBudgetMib) && c.memoryBudgetMib >= 0 && c.memoryBudgetMib <= 1e9,
       "memory_budget_mib must be in [0, 1e9] MiB (0 = no budget)");
  need(c.emissionTextureResolution >= 0, "emission_texture_resolution must be >= 0 (0 = the albedo's)");
  need(c.initWhitePoint >= 0 && c.initWhitePoint <= 1, "init_white_point must be in [0, 1] (0 = off)");
  need(c.lightMinUnexplained >= 0 && c.lightMinUnexplained <= 1, "light_min_unexplained must be in [0, 1]");
  need(std::isfinite(c.lightSignificance) && c.lightSignificance >= 0, "light_significance must be >= 0");
  need(std::isfinite(c.lightMinContrast) && c.lightMinContrast >= 0, "light_min_contrast must be >= 0");
  need(c.lightEvidenceTexels >= 1 && c.lightEvidenceTexels <= (1 << 20), "light_evidence_texels must be in [1, 2^20]");
  need(c.emissionRefitIterations >= 0, "emission_refit_iterations must be >= 0");
  need(c.clippedScalePaths >= 2 && c.clippedScalePaths <= 4096, "clipped_scale_paths must be in [2, 4096]");
  need(std::set<std::string>(c.lights.begin(), c.lights.end()).size() == c.lights.size(),
       "lights names an object twice");
  need(c.pruneFraction >= 0 && c.pruneFraction < 1, "prune_fraction must be in [0, 1)");
  need(c.emitterRadianceFraction >= 0 && c.emitterRadianceFraction <= 1, "emitter_radiance_fraction must be in [0, 1]");
  need(c.highlightMinPairs >= 1, "highlight_min_pairs must be >= 1");
  need(std::isfinite(c.highlightMinContrast), "highlight_min_contrast must be finite");
  need(c.gainReferenceFrame >= -1, "gain_reference_frame must be a frame index, or -1 (geometric mean 1)");
  need(c.gainMemory >= 0 && c.gainMemory < 1, "gain_memory must be in [0, 1)");
  need(c.poseRenderSpp >= 1 && c.poseRenderSpp <= 4096, "pose_render_spp must be in [1, 4096]");
  need(c.poseImageWidth >= 32 && c.poseImageWidth <= 8192, "pose_image_width must be in [32, 8192]");
  need(c.posePyramidLevels >= 1 && c.posePyramidLevels <= 8, "pose_pyramid_levels must be in [1, 8]");
  need(c.checkpointEvery >= 1 && c.metricsEvery >= 1, "checkpoint_every and metrics_every must be >= 1");
  need(c.stopAfterIterations >= 0, "stop_after_iterations must be >= 0 (0 = run to the end)");
}

// Measured in docs/notes/2026-11-28-quality-presets.md. The albedo stages carry most of the cost
// (73% on the demo capture) and most of what a longer fit buys: `draft` cuts them to a quarter
// and halves the other stages (the lights and their emission hold at a third of the emission
// stage); `best` lets them run twice the default's cap, which the albedo of captures with many
// texels per frame needs (the 1K room) and others do not.
FitConfig FitConfig::forQuality(FitQuality quality) {
  FitConfig c;
  switch (quality) {
    case FitQuality::Draft:
      c.emissionIterations = 100;
      c.maxStageIterations = 500;
      c.materialIterations = 150;
      c.emissionTextureIterations = 50;
      break;
    case FitQuality::Default:
      break;
    case FitQuality::Best:
      c.maxStageIterations = 4000;
      break;
  }
  return c;
}

FitConfig FitConfig::load(const std::filesystem::path& path) { return load(path, FitConfig{}); }

FitConfig FitConfig::load(const std::filesystem::path& path, FitConfig base) {
  return fromJson(readJson(path), path.string(), std::move(base));
}

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
          if constexpr (std::is_enum_v<T>) {
            if (!v.is_string() || !enumFromName(v.get<std::string>(), *p))
              fail("{}: '{}' must be {}, not {}", where, key, enumChoices<T>(), v.dump());
            return;
          } else if constexpr (std::is_same_v<T, std::vector<std::string>>)
            ok = v.is_array() && std::all_of(v.begin(), v.end(), [](const Json& e) { return e.is_string(); });
          else
            ok = std::is_same_v<T, bool>    ? v.is_boolean()
                 : std::is_same_v<T, float> ? v.is_number()
                                            : v.is_number_integer();
          if (!ok) fail("{}: '{}' has the wrong type ({})", where, key, v.type_name());
          // Numbers are checked in the type they are used in: get<int>() would wrap 4294967297 onto
          // 1, a negative seed would wrap, and 1e39 is infinite as a float.
          if constexpr (std::is_same_v<T, int>)
            *p = static_cast<int>(jsonInteger(v, INT_MIN, INT_MAX, where, key));
          else if constexpr (std::is_same_v<T, uint64_t>)
            *p = v.is_number_unsigned() ? v.get<uint64_t>()
                                        : static_cast<uint64_t>(jsonInteger(v, 0, INT64_MAX, where, key));
          else if constexpr (std::is_same_v<T, float>)
            *p = finiteFloat(v, where, key);
          else
            *p = v.get<T>();
        },
        field);
  });
  for (const auto& [key, value] : j.items())
    if (!known.count(key)) fail("{}: unknown key '{}' (docs/user/fit-config.md lists them)", where, key);
  c.validate(where);
  return c;
}

Json FitConfig::toJson() const {
  Json j = Json::object();
  forEachConfigKey(const_cast<FitConfig&>(*this), [&](const char* key, ConfigField field) {
    std::visit(
        [&](auto* p) {
          if constexpr (std::is_enum_v<std::remove_pointer_t<decltype(p)>>)
            j[key] = enumName(*p);
          else
            j[key] = *p;
        },
        field);
  });
  return j;
}

}  // namespace relume
