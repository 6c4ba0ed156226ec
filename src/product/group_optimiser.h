// The fit's optimiser, per parameter group (params/parameters.h enumerates the groups): which
// entries may move (the masks), the step (damped Gauss-Newton for the albedo, masked Adam for
// the rest; optim/), the Polyak averages of the settling stage, and how that state follows the
// albedo to a finer resolution or starts over when the light sources change.
#pragma once
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "optim/adam.h"
#include "optim/gauss_newton.h"
#include "params/gradients.h"
#include "params/parameters.h"
#include "product/fit_checkpoint.h"
#include "product/fit_config.h"
#include "product/fit_schedule.h"
#include "product/fit_workspace.h"

namespace relume {

// Entries whose gradient is zeroed before the step: texels no frame observed (and the dilated
// ring beyond them), the held albedo of light sources (also its Gauss-Newton curvature, with
// which a texel would still move towards its running fit), the materials of objects without
// observed highlights, and the emission of objects that are not light sources.
struct GradientMasks {
  const TexelSpace& space;
  const TriangleMesh& mesh;
  std::span<const uint8_t> albedoHeld;       // per object
  std::span<const uint8_t> materialsFitted;  // per object
  std::span<const uint8_t> emits;            // per object

  void apply(ParamGroup& g, std::vector<float>& albedoCurvature, std::span<const uint32_t> splattedAlbedo) const;
};

class GroupOptimiser {
 public:
  explicit GroupOptimiser(const FitConfig& c) : c_(c) {}
  // Emission steps are relative, with a floor at emission_floor x this (the brightest observation).
  void setRadianceScale(float scale) { radianceScale_ = scale; }

  // One step of group `g` at iteration `it` of stage `st` (its gradient already masked), then its
  // Polyak average when the stage settles it. Returns whether that average starts here.
  bool step(ParamGroup& g, std::span<const float> albedoCurvature, std::span<const uint32_t> splattedAlbedo,
            const Stage& st, int it);
  // At the end of stage `st`: the groups it settles take their averages.
  void settle(std::span<ParamGroup> groups, const Stage& st) const;
  // Then, once what the settled albedo's standard errors need has been read, the state of the
  // kinds `st` settled (their steps' state and averages) is freed: no later stage steps them, and
  // at 4096^2 the albedo's is most of what a fit holds while it smooths and writes its result.
  void release(std::span<const ParamGroup> groups, const Stage& st);

  // The albedo's state follows it to the finer texel space `to`.
  void upsampleAlbedo(const TexelSpace& from, const TexelSpace& to, const TriangleMesh& mesh);
  // The light sources changed: the albedo's running fits and averages, and the emission's Adam
  // state, start over.
  void restartAfterLightChange();

  bool newtonAlbedo() const { return c_.albedoStep == AlbedoStep::GaussNewton; }
  // Per albedo entry, the standard error of the Gauss-Newton fit, at most the albedo's domain
  // width `bound` (negative where unknown); empty without albedo_standard_error or before the
  // albedo has stepped.
  std::vector<float> albedoStandardError(float bound) const;
  // The albedo's Gauss-Newton state (empty when the albedo steps by Adam or has not stepped).
  const GaussNewtonState& albedoNewton() const { return newton_; }
  // Every group's state, for checkpoints (`groups` of the appearance being saved or restored).
  void serialise(CheckpointIo& io, std::span<ParamGroup> groups, size_t albedoEntries);
  double stateBytes() const;    // Adam moments and Gauss-Newton sums
  double averageBytes() const;  // Polyak means

 private:
  AdamSettings adamFor(const ParamGroup& g, float lrScale) const;

  const FitConfig& c_;
  float radianceScale_ = 1e-6f;
  std::map<std::string, AdamState> adam_;
  GaussNewtonState newton_;  // the albedo's, with albedo_step gauss-newton
  std::map<std::string, PolyakAverage> polyak_;
};

}  // namespace relume
