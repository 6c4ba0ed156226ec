#include "product/fit_schedule.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace relume {
namespace {
constexpr int kScaleProbes = 4;  // at most: each a quarter of the first albedo stage
}  // namespace

float Stage::settleScale(int it, float finalFraction) const {
  const float half = 0.5f * iterations;
  return it < half ? 1.0f : 1.0f - (1.0f - finalFraction) * (it - half) / std::max(1.0f, half);
}

int Stage::averageFrom(ParamKind kind, float fraction) const {
  return settles.active(kind) && fraction > 0
             ? iterations - std::max(1, static_cast<int>(std::lround(fraction * iterations)))
             : iterations;
}

std::vector<Stage> buildSchedule(const FitConfig& c, const std::vector<int>& resolutions,
                                 const std::function<size_t(int)>& sampleableAt) {
  using K = ParamKind;
  const int finalRes = resolutions.back();
  // The iterations of albedo_passes at `res`, without max_stage_iterations (at most 1e8), and with it.
  auto passIterations = [&](int res) {
    const double n = std::ceil(c.albedoPasses * sampleableAt(res) /
                               std::max(1, c.sampler == SamplerKind::Texture ? c.batchTexels : c.imageRays));
    return static_cast<int>(std::clamp(n, 1.0, 1e8));
  };
  auto albedoIterations = [&](int res) { return std::min(passIterations(res), c.maxStageIterations); };
  auto passStage = [&](Stage& st, int longest) {
    st.lengthFromPasses = true;
    st.longest = std::max(st.iterations, longest);
  };
  std::vector<Stage> s;
  const RayFootprint rays = c.rayFootprint;
  const ParamMask emission =
      c.emitterParameterisation ? ParamMask::only({K::Emission}) : ParamMask::only({K::EmissionTexture});
  if (!c.coarseToFine) {
    ParamMask all = ParamMask::only({K::Albedo, K::Roughness, K::Specular});
    all.bits |= emission.bits;
    int n = c.emissionIterations + c.materialIterations;
    for (int r : resolutions) n += albedoIterations(r);
    s.push_back({"all", all, finalRes, n, false, false, all, rays});
    passStage(s.back(), n);
    return s;
  }
  // Its unknowns are per object (with emitter_parameterisation), so a ray may stand for a whole
  // pixel: an emitter seen as a few pixels is mixed with its surroundings in every one of them,
  // and a ray through the emitter's own point compared with that mixture dims it (docs/design/fit.md). Per-texel
  // unknowns are better served by points: a pixel ray's residual and sensitivity belong to different texels, noise a
  // per-texel step cannot average away.
  s.push_back({"emission",
               emission,
               resolutions.front(),
               c.emissionIterations,
               c.emitterParameterisation,
               false,
               {0},
               c.emissionFootprint});
  // Then the albedo at the first resolution, and only then roughness and specular with it: while
  // the albedo is still near its (too dark) init, the specular lobe of a rough object makes up
  // for it (measured on the room: the walls' specular went to 1.0 whether it was fitted before or
  // together with the first albedo steps).
  // Emission stays where stage 1 put it: there the emitters are pinned by the frames that see them
  // (I = E), while fitted together with the albedo it drifts along the near-null direction
  // "brighter lights, darker albedo" (room: 3% after stage 1, 10% after the albedo stages).
  const ParamMask albedo = ParamMask::only({K::Albedo});
  // When the first decision finds lights seen only saturated, short albedo stages each end in
  // their scale (clipped_light_scale.h). Each after the first runs while the last scale moved them
  // by more than its error: where the albedo sat at 1 under far too dark lights, the surfaces lit
  // the rest of the room too dimly, and a scale falls short of the truth until the albedo has
  // followed it. The albedo stage proper then fits under the last scale.
  if (c.emitterParameterisation && c.clippedLightScale)
    for (int k = 1; k <= kScaleProbes; ++k) {
      s.push_back({k == 1 ? fmt::format("scale_probe@{}", resolutions.front())
                          : fmt::format("scale_probe_{}@{}", k, resolutions.front()),
                   albedo, resolutions.front(), std::max(1, albedoIterations(resolutions.front()) / 4)});
      passStage(s.back(), passIterations(resolutions.front()) / 4);
      s.back().scaleClippedLightsAfter = true;
      s.back().onlyWithClippedLights = true;
      s.back().afterClippedScale = k > 1;
    }
  s.push_back({fmt::format("albedo@{}", resolutions.front()), albedo, resolutions.front(),
               albedoIterations(resolutions.front())});
  passStage(s.back(), passIterations(resolutions.front()));
  // The light sources decided again now that the albedo explains the lit surfaces; when that
  // changed them, their emission is fitted again (the albedo held) before the materials.
  const bool redecide =
      c.emitterParameterisation && c.lightTest == LightTest::Reflector && c.lightRedecide && c.lights.empty();
  s.back().redecideAfter = redecide;
  // The poses are refined once the albedo explains the frames (pose_refinement.h), and again after
  // the material stage when finer albedo stages follow to use them.
  s.back().refinePosesAfter = true;
  // The fill belongs to the reflector test's light estimate (with the hint too, so the two compare).
  s.front().fillUnobservedAfter = s.back().fillUnobservedAfter = c.lightTest == LightTest::Reflector;
  const size_t refitStage = s.size();
  if (redecide && c.emissionRefitIterations > 0)
    s.push_back({"emission_refit", emission, resolutions.front(), c.emissionRefitIterations});
  // With material_stage_settles, roughness and specular settle in their own stage and the finer
  // albedo stages fit the albedo alone: the material texels make the 1K room's albedo@1024
  // iterations 1.3x dearer, but without them its albedo came out worse.
  const ParamMask materials = ParamMask::only({K::Albedo, K::Roughness, K::Specular});
  const ParamMask afterMaterials = c.materialStageSettles ? albedo : materials;
  const size_t materialStage = s.size();
  s.push_back({"materials", materials, resolutions.front(), c.materialIterations});
  s.back().refinePosesAfter = resolutions.size() > 1;
  for (size_t i = 1; i < resolutions.size(); ++i) {
    s.push_back(
        {fmt::format("albedo@{}", resolutions[i]), afterMaterials, resolutions[i], albedoIterations(resolutions[i])});
    passStage(s.back(), passIterations(resolutions[i]));
  }
  // The albedo stages proper (not the probes, whose scale wants a fixed share of the first) may
  // run all their passes, ending on convergence. Under a time budget they run what its plan gives
  // them (up to all their passes), and end sooner if they converge.
  if (c.stopOnConvergence)
    for (Stage& st : s)
      if (st.lengthFromPasses && st.name.starts_with("albedo@")) {
        st.endsOnConvergence = true;
        if (c.timeBudget == 0) st.iterations = st.longest;
      }
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

double texelsDrawn(const FitConfig& c, const Stage& st) {
  double n = c.sampler == SamplerKind::Texture ? c.batchTexels
                                               : static_cast<double>(c.imageRays) / std::max(1, c.framesPerTexel);
  if (st.active.active(ParamKind::Roughness)) n += c.materialBatchTexels + c.highlightBatchTexels;
  if (st.focusEmitters) n += c.emissionBatchTexels;
  return std::max(1.0, n);
}

}  // namespace relume
