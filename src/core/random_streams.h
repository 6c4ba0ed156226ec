// Every random stream relume draws from, by name. A stream's generator is seeded with
// hashTuple({..., tag}); a tag used once keeps two streams from drawing the same numbers. The
// values are fixed: changing one changes every result that draws from it.
#pragma once
#include <array>
#include <cstdint>

namespace relume {

enum class RandomStream : uint64_t {
  FilmPixel = 0x7265,               // render/film.cpp: a pixel's samples
  PrimalPass = 0x5031,              // adjoint/solver.cpp: the primal pass of a ray
  AdjointPass = 0x5032,             // adjoint/solver.cpp: the adjoint pass of a ray
  TextureSampler = 0x7473,          // sampling/samplers.cpp: texel and frame draws
  ImageSampler = 0x6973,            // sampling/samplers.cpp: pixel draws
  HighlightProbe = 0x70726f,        // product/fit_batches.cpp: which texels see a light reflected
  MaterialBatch = 0x6d6174,         // product/fit_batches.cpp: the fitted objects' extra texels
  HighlightBatch = 0x686c74,        // product/fit_batches.cpp: their highlight texels
  HighlightAbsence = 0x686162,      // product/light_decisions.cpp: the lobe samples at each roughness
  EmissionBatch = 0x656d69,         // product/fit_batches.cpp: each light-source candidate's texels
  LightDecision = 0x6c69676874,     // product/light_decisions.cpp: each decision's evidence rays
  ReflectorBound = 0x7265666c,      // product/light_evidence.cpp: the albedo-1 bound's paths
  MirrorPath = 0x6d697272,          // product/light_evidence.cpp: the perfect-mirror paths
  ClippedLightScale = 0x636c6970,   // product/clipped_light_scale.cpp: its texels and paths
  ExperimentRays = 0x7261,          // lab/experiment.cpp: a gradient experiment's rays
  ExperimentPerturbation = 0x7065,  // lab/experiment.cpp: its current parameters' perturbation
  LeakRays = 0x6c65,                // lab/profile.cpp: the edge-leak study's rays
  SynthPose = 0x737031,             // scenes/imperfections.cpp: a training frame's written pose
  SynthWhiteBalance = 0x737032,     // scenes/imperfections.cpp: a frame's white-balance gains
  SynthExposureDrift = 0x737033,    // scenes/imperfections.cpp: a frame's auto-exposure gain
  SynthSensorNoise = 0x737034,      // scenes/imperfections.cpp: a frame's shot and read noise
  SynthMeshNoise = 0x737035,        // scenes/imperfections.cpp: a mesh vertex's displacement
  SynthMissingFrames = 0x737036,    // scenes/imperfections.cpp: which training frames are left out
  PoseRefinement = 0x706f7365,      // product/fit.cpp: the renders frames are aligned with
};

inline constexpr uint64_t streamTag(RandomStream s) { return static_cast<uint64_t>(s); }

namespace detail {
inline constexpr std::array kAllRandomStreams{
    RandomStream::FilmPixel,          RandomStream::PrimalPass,       RandomStream::AdjointPass,
    RandomStream::TextureSampler,     RandomStream::ImageSampler,     RandomStream::HighlightProbe,
    RandomStream::MaterialBatch,      RandomStream::HighlightBatch,   RandomStream::EmissionBatch,
    RandomStream::LightDecision,      RandomStream::ReflectorBound,   RandomStream::MirrorPath,
    RandomStream::ClippedLightScale,  RandomStream::ExperimentRays,   RandomStream::ExperimentPerturbation,
    RandomStream::LeakRays,           RandomStream::SynthPose,        RandomStream::SynthWhiteBalance,
    RandomStream::SynthExposureDrift, RandomStream::SynthSensorNoise, RandomStream::SynthMeshNoise,
    RandomStream::SynthMissingFrames, RandomStream::HighlightAbsence, RandomStream::PoseRefinement};
constexpr bool allTagsDistinct() {
  for (size_t i = 0; i < kAllRandomStreams.size(); ++i)
    for (size_t j = i + 1; j < kAllRandomStreams.size(); ++j)
      if (kAllRandomStreams[i] == kAllRandomStreams[j]) return false;
  return true;
}
static_assert(allTagsDistinct(), "two random streams share a tag");
}  // namespace detail

}  // namespace relume
