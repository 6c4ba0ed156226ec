// The fit's configuration: every choice of the method is a key, so the paper's ablation can be
// rerun. One table of keys (fit_config.cpp) serves loading, validation, writing and the
// reference in docs/user/fit-config.md, which a test keeps in step with it. The measurements
// behind each default are in docs/design/fit.md and docs/notes/.
#pragma once
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "adjoint/solver.h"
#include "core/enum_names.h"
#include "io/json.h"
#include "product/frame_gains.h"
#include "sampling/samplers.h"

namespace relume {

enum class SamplerKind { Texture, Image };    // texture space (the paper's) or image space (the ablation's baseline)
enum class AlbedoStep { GaussNewton, Adam };  // damped diagonal Gauss-Newton (optim/gauss_newton.h) or the paper's Adam
enum class LightTest { Reflector, RadianceFraction };  // how light sources are told from lit surfaces
// The settled albedo smoothed by its standard errors (optim/texel_smoothing.h): not at all, by
// them alone, or also kept from crossing the median init's edges (the frames').
enum class AlbedoSmoothing { None, Albedo, GuideEdges };
// Pose refinement (product/pose_refinement.h): auto = on when the capture's poses come from a
// reconstruction (COLMAP, or a transforms.json that does not say `exact_poses`). Off by default:
// on the Cycles White Room it moved 1 cm position errors to 3.5 cm (docs/notes, pose refinement).
enum class RefinePoses { Auto, On, Off };
enum class UnalignedFrames { Keep, Drop };  // a frame the refinement cannot align: kept at its pose, or dropped
// `relume fit --quality`: the schedule a user picks without reading the measurements behind it
// (FitConfig::forQuality; docs/user/fit-config.md#quality).
enum class FitQuality { Draft, Default, Best };

template <>
struct EnumNames<SamplerKind> {
  static constexpr std::array<std::pair<SamplerKind, std::string_view>, 2> values{
      {{SamplerKind::Texture, "texture"}, {SamplerKind::Image, "image"}}};
};
template <>
struct EnumNames<AlbedoStep> {
  static constexpr std::array<std::pair<AlbedoStep, std::string_view>, 2> values{
      {{AlbedoStep::GaussNewton, "gauss-newton"}, {AlbedoStep::Adam, "adam"}}};
};
template <>
struct EnumNames<AlbedoSmoothing> {
  static constexpr std::array<std::pair<AlbedoSmoothing, std::string_view>, 3> values{
      {{AlbedoSmoothing::None, "none"}, {AlbedoSmoothing::Albedo, "albedo"}, {AlbedoSmoothing::GuideEdges, "guide_edges"}}};
};
template <>
struct EnumNames<RefinePoses> {
  static constexpr std::array<std::pair<RefinePoses, std::string_view>, 3> values{
      {{RefinePoses::Auto, "auto"}, {RefinePoses::On, "on"}, {RefinePoses::Off, "off"}}};
};
template <>
struct EnumNames<UnalignedFrames> {
  static constexpr std::array<std::pair<UnalignedFrames, std::string_view>, 2> values{
      {{UnalignedFrames::Keep, "keep"}, {UnalignedFrames::Drop, "drop"}}};
};
template <>
struct EnumNames<FitQuality> {
  static constexpr std::array<std::pair<FitQuality, std::string_view>, 3> values{
      {{FitQuality::Draft, "draft"}, {FitQuality::Default, "default"}, {FitQuality::Best, "best"}}};
};
template <>
struct EnumNames<LightTest> {
  static constexpr std::array<std::pair<LightTest, std::string_view>, 2> values{
      {{LightTest::Reflector, "reflector"}, {LightTest::RadianceFraction, "radiance_fraction"}}};
};

struct FitConfig {
  // Sampling
  SamplerKind sampler = SamplerKind::Texture;
  int batchTexels = 8192;  // B: texels per iteration (texture sampler)
  int framesPerTexel = 4;  // K: frames connected per texel
  // While roughness and specular are fitted, this many more texels per iteration from the fitted
  // objects only: a glossy object is a few percent of the texels and its highlight a few percent
  // of its rays, so its per-object gradient is otherwise too noisy to settle.
  int materialBatchTexels = 2048;
  int highlightBatchTexels = 0;  // and this many from their texels that see a light reflected
  // In the emission stage, this many more texels per iteration shared evenly between the
  // light-source candidates: each object's emission is weighed against its own pixels, however
  // small it is.
  int emissionBatchTexels = 1024;
  RayFootprint materialFootprint = RayFootprint::Point;  // what the material batch's rays are compared with
  int imageRays = 16384;                                 // rays per iteration (image sampler)
  RayFootprint rayFootprint = RayFootprint::Point;       // what a ray is compared with (sampling/samplers.h)
  // The emission stage's: an emitter seen as a few pixels is mixed with its surroundings in each.
  RayFootprint emissionFootprint = RayFootprint::Pixel;
  // Independent (primal, adjoint) pairs per connection: 2 halves the variance of each ray's
  // albedo sensitivity where the light arrives through 1-spp indirect paths.
  int samplesPerRay = 2;
  int maxDepth = kDefaultMaxDepth;  // scattering vertices (9 = Cycles' max bounces 8), as synth renders
  GradientMode gradients = GradientMode::Direct;
  EmitterGradients emitterGradients = EmitterGradients::Strict;
  Pairing pairing = Pairing::Decorrelated;
  // Russian roulette after `rouletteDepth` vertices (survival = the path's throughput, clamped to
  // [0.05, 0.95]; unbiased): 9.3 rays per path instead of 16 at the same albedo error.
  bool russianRoulette = true;
  int rouletteDepth = 5;
  // Optimiser. Learning rates above the paper's for albedo-by-Adam and the materials' because a
  // texel here gets a few noisy rays per touch (the paper's GPU batches gave it many).
  float lrAlbedo = 0.02f, lrRoughness = 0.02f, lrSpecular = 0.02f;
  AlbedoStep albedoStep = AlbedoStep::GaussNewton;
  // Gauss-Newton: fraction of the Newton step taken once a texel has had 1/damping visits
  // (1/visit before): the estimate averages its last ~1/damping visits, which sets its noise.
  float albedoDamping = 0.005f;
  // Gauss-Newton: each texel's standard error, from the spread of its visits (8 more bytes per
  // albedo entry); written as result/albedo_stderr.exr and used by the smoothing.
  bool albedoStandardError = true;
  AlbedoSmoothing albedoSmoothing = AlbedoSmoothing::GuideEdges;
  int albedoSmoothingRadius = 2;  // texels; the spatial kernel's sigma is half of it
  float lrEmission = 0.2f;  // relative: a step is lr * max(E, emissionFloor * brightest observation)
  float emissionFloor = 0.02f;
  // Relative, per texel: every light sample splats onto some emitter texel, so each is touched
  // every iteration with a low-SNR gradient, and masked Adam jitters it by ~lr per step.
  float lrEmissionTexture = 0.002f;
  // The settling stage of each kind: constant lr for its first half, then linear down to this.
  float lrFinalFraction = 0.1f;
  bool maskedAdam = true, perEntrySteps = true;
  float gradientClamp = 10.0f;  // x the median nonzero gradient magnitude of the group; 0 = off
  float polyakFraction = 0.1f;  // of the settling stage averaged; 0 = off
  // The same for the per-object roughness and specular, which a few highlight rays touch every
  // iteration, so their last iterates wander by ~lr.
  float materialPolyakFraction = 0.5f;
  // true: roughness and specular settle at the end of the material stage and the finer albedo
  // stages fit the albedo alone (faster; the albedo came out worse); false: they settle with the
  // last albedo stage.
  bool materialStageSettles = false;
  // Schedule
  int emissionIterations = 200, materialIterations = 300, emissionTextureIterations = 100;
  float albedoPasses = 100.0f;           // albedo stage length: expected draws per sampleable texel
  int maxStageIterations = 2000;         // cap on any albedo stage
  // true: each albedo stage (not the scale probes) may run up to albedo_passes, ending once its
  // albedo has stopped moving by more than its noise (optim/albedo_convergence.h) and that noise
  // is small: checked every `convergence_check_passes`, ended when the movement is at most
  // `convergence_ratio` times what the noise alone gives and the median standard error of the
  // albedo at most `convergence_standard_error` (a stage that settles unknowns then runs as long
  // again, its settling half). max_stage_iterations does not apply to them. false: the fixed
  // lengths above.
  bool stopOnConvergence = false;
  float convergenceRatio = 1.05f;
  float convergenceStandardError = 0.03f;
  float convergenceCheckPasses = 2.0f;
  int maxResolution = 0;                 // cap on the final albedo resolution; 0 = what the frames resolve
  // Seconds the fit may take: the stage lengths are chosen from measured iteration costs so that
  // it ends then (product/time_budget.h); 0 = the fixed schedule above.
  float timeBudget = 0;
  // MiB the fit may hold at its peak: it takes the finest albedo resolution whose predicted peak
  // fits, or refuses up front (product/memory_budget.h); 0 = no budget.
  float memoryBudgetMib = 0;
  int emissionTextureResolution = 1024;  // cap on the emission textures' atlas resolution; 0 = the albedo's
  // Light sources (docs/design/light-sources.md). Reflector: an object is a light when no
  // reflector with albedo <= 1 and the model's specular lobe returns its observed radiance,
  // decided after the emission stage and again after the first albedo stage. Radiance fraction
  // (the ablation): emission >= emitter_radiance_fraction of its observed radiance, decided once.
  LightTest lightTest = LightTest::Reflector;
  float lightMinUnexplained = 0.5f;   // share of its radiance no reflector returns
  float lightSignificance = 3.0f;     // standard errors the unexplained radiance must clear
  float lightMinContrast = 4.0f;      // a light's radiance over the median object's; 0 = off
  bool lightSaturatedFloor = true;    // an object seen only saturated is judged by its floor
  int lightEvidenceTexels = 256;      // texels per object drawn for each decision
  bool lightRedecide = true;          // decide again after the first albedo stage
  int emissionRefitIterations = 100;  // emission-only stage after a re-decision that changed the lights
  std::vector<std::string> lights;    // hint: exactly these objects (by name) emit; no decision taken
  // Lights whose pixels all clip: after the first albedo stage their emission is scaled to make each
  // object's albedo most uniform (product/clipped_light_scale.h); false = keep the init's scale.
  bool clippedLightScale = true;
  // Its light from the surfaces in view taken at what the frames show of them, not at the fit's
  // albedo, which sits at 1 where the lights are still too dark (clipped_light_scale.cpp).
  bool clippedScaleShownRadiance = true;
  // Paths traced per drawn ray for each of that scale's terms. Their noise comes out of each
  // object's spread only to first order: at the White Room's truth 8 paths biased its scale and 64
  // did not, but in the fit 64 left the room's panels further off (docs/notes/2026-12-02-scale-path-noise.md).
  int clippedScalePaths = 8;
  // In that scale, the first vertex's specular lobe apart from its diffuse one, and each object's
  // terms also under kFirstVertexMaterials (clipped_light_scale.h), each object keeping the one its
  // albedo is most uniform under at the lights' shared scale; false: both lobes as one, the fit's
  // materials.
  bool clippedScaleMaterialChoice = true;
  // Then, or where that scale is not known, the lights raised until no object's albedo exceeds 1
  // (albedoCeiling, at light_significance of its errors); false: the uniformity alone.
  bool clippedScaleAlbedoCeiling = true;
  // After their last scale, each one's colour measured where its outline mixes into its pixels
  // unclipped (product/silhouette_colour.h), where that is known; false = the colour the emission
  // stage and the per-channel scales gave them.
  bool clippedLightSilhouetteColour = true;
  // A light source's radiance is all emission (albedo 0, not fitted): from any view a Lambertian
  // emission and a diffuse reflection look the same, and windows and shades transmit their light.
  bool lightAlbedoZero = true;
  // That emission from a light's unclipped pixels where it also has clipped ones (seen unclipped
  // only in a bracket's darker frames): each clipped value raised to the unclipped mean. false =
  // clipped values taken as they are, the emission fitted from the light it casts kept when brighter.
  bool lightUnclippedEmission = true;
  float pruneFraction = 0.02f;            // light sources below this fraction of the total power go to 0
  float emitterRadianceFraction = 0.75f;  // light_test radiance_fraction's threshold
  // Roughness and specular are fitted only where the frames show a highlight: texels seen both
  // with a light in the mirror direction and without, at least `highlightMinPairs` of them,
  // brighter with it by at least `highlightMinContrast` (mean minus two standard errors).
  int highlightMinPairs = 8;
  float highlightMinContrast = 0.1f;
  // On objects seen both ways without such a highlight, the roughnesses that would have shown one
  // are ruled out and the roughness takes the middle of the rest (light_decisions.h); false = kept
  // at the init.
  bool highlightAbsence = true;
  // The uniform batch leaves out a ray whose reference disagrees with its texel's median beyond
  // prepare's agreement ratio, on texels seen at least 5 times (product/confidence.h): the mesh is
  // not where the frame saw the surface (a missing object, a misregistered edge). The material and
  // emission batches keep theirs (a highlight disagrees too).
  bool dropDisagreeing = false;
  bool emitterParameterisation = true, medianInit = true, coarseToFine = true, emissionTextures = true;
  float initWhitePoint = 0.8f;  // the median init's 95th-percentile texel becomes this albedo; 0 = off
  // Photometry (product/frame_gains.h): per-frame gains estimated with the reconstruction.
  FrameGainMode frameGains = FrameGainMode::Auto;
  int gainReferenceFrame = -1;  // the frame whose gain is 1; -1: the gains' geometric mean is 1
  float gainMemory = 0.9f;      // per-iteration decay of a frame's evidence sums (~1/(1-m) iterations)
  bool gainRefine = false;      // update the gains in the fit too (closed form), not only prepare's
  // Poses: each frame aligned with the reconstruction's render after the first albedo stage and
  // after the material stage (docs/design/poses.md).
  RefinePoses refinePoses = RefinePoses::Off;
  int poseRenderSpp = 16;     // paths per pixel of the render a frame is aligned with
  int poseImageWidth = 320;   // frames are aligned at most this wide (box-downscaled)
  int posePyramidLevels = 3;  // each half the last: corrections up to ~2^levels pixels are found
  UnalignedFrames unalignedFrames = UnalignedFrames::Keep;
  uint64_t seed = 1;
  int checkpointEvery = 100, metricsEvery = 10;
  int stopAfterIterations = 0;  // stop (with a checkpoint) after this many iterations; 0 = run to the end

  // The schedule of a quality; a config file's keys and the command line's options apply over it.
  // Only stage lengths differ: every choice of the method stays the default.
  static FitConfig forQuality(FitQuality quality);
  // The defaults, or `base`, with the keys of the file at `path` (unknown key or wrong value: one-line error).
  static FitConfig load(const std::filesystem::path& path);
  static FitConfig load(const std::filesystem::path& path, FitConfig base);
  // `base` with the keys `j` gives (the same checks; `where` names the source in errors).
  static FitConfig fromJson(const Json& j, const std::string& where, FitConfig base);
  Json toJson() const;  // every key, enums by name
  // Throws relume::Error naming `where` and the key when a value is out of its range.
  void validate(const std::string& where) const;
};

}  // namespace relume
