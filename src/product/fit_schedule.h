// The fit's schedule: its stages, what each fits, at which resolution, for how long, and what
// happens at its boundaries (Nimier-David et al. 2021, 3.4, extended with the light-source
// decisions; docs/design/fit.md). Defaults: (1) per-object emission, then the light sources are
// decided; (2) albedo at the first resolution, then decided again (and the emission refitted if
// that changed them); (3) + per-object roughness and specular on objects with observed
// highlights; (4) the same, coarse to fine up to what the frames resolve; (5) emission textures.
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "params/parameters.h"
#include "product/fit_config.h"
#include "sampling/samplers.h"

namespace relume {

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
  bool redecideAfter = false;                    // the light sources are decided again at its end
  bool refit = false;                            // emission only, run when the re-decision changed the light sources
  bool focusEmitters = false;                    // draws emission_batch_texels from the light-source candidates
  bool fillUnobservedAfter = false;              // unobserved texels take their object's mean albedo at its end
  bool scaleClippedLightsAfter = false;          // lights seen only saturated are scaled at its end
  bool onlyWithClippedLights = false;            // run only when the lights include such lights
  bool afterClippedScale = false;                // run only while their last scale moved them
  bool refinePosesAfter = false;                 // the frames' poses are refined at its end (with refine_poses)
  bool lengthFromPasses = false;                 // its length is albedo passes
  // With stop_on_convergence: it runs up to its albedo passes and ends once its albedo has
  // stopped moving by more than its noise (product/fit.cpp); `convergedAt` is the iteration at
  // which it did (0: not yet).
  bool endsOnConvergence = false;
  int convergedAt = 0;
  // With a time budget, the most it may run: its albedo_passes without max_stage_iterations.
  int longest = 0;

  // The learning-rate factor at iteration `it` for the kinds this stage settles: 1 over its first
  // half, then linear down to `finalFraction` (1 for the kinds it does not settle).
  float settleScale(int it, float finalFraction) const;
  // The iteration from which `kind`'s Polyak average is kept: the last `fraction` of the stage
  // when it settles that kind, never otherwise (returns `iterations`).
  int averageFrom(ParamKind kind, float fraction) const;
};

// The stages of a fit whose albedo resolutions are `resolutions` (coarse to fine);
// `sampleableAt(res)` estimates the sampleable texels at a resolution (stage lengths are passes
// over them).
std::vector<Stage> buildSchedule(const FitConfig& c, const std::vector<int>& resolutions,
                                 const std::function<size_t(int)>& sampleableAt);

// The texels an iteration of `st` draws: the uniform batch (the image sampler's rays, counted as
// frames_per_texel to a texel), and its focus sets where the configuration has them (the cost
// model of a time budget, product/time_budget.h).
double texelsDrawn(const FitConfig& c, const Stage& st);

}  // namespace relume
