// What each object is: a light source, a reflector, out of the model (a mirror), and whether the
// frames show highlights on it; and the decisions that say so (docs/design/light-sources.md):
// objects no frame sees are no candidates, the `lights` hint, the reflector test after the
// emission stage and again after the first albedo stage (light_evidence.h), the radiance-fraction
// pruning of the ablation, and the highlight test before the material stage.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "io/json.h"
#include "params/parameters.h"
#include "product/fit_batches.h"
#include "product/fit_checkpoint.h"
#include "product/fit_config.h"
#include "product/clipped_light_scale.h"
#include "product/fit_workspace.h"
#include "product/frame_gains.h"
#include "product/light_evidence.h"

namespace relume {

struct ObjectRoles {
  std::vector<uint8_t> emitter;           // a light-source candidate, or a light once decided
  std::vector<uint8_t> outOfModel;        // excluded from emission and albedo (light_evidence.h)
  std::vector<uint8_t> highlight;         // roughness and specular fitted
  uint8_t refitEmission = 0;              // the re-decision changed the light sources: run emission_refit
  uint8_t clippedLights = 0;              // the first decision's lights include some seen only saturated
  uint8_t clippedScaleMoving = 0;         // their last scale moved them by more than its error
  uint8_t clippedScaleChose = 0;          // a scale has chosen the first vertex's materials
  Json lightDecisions = Json::array();    // each decision's evidence (result/lights.json)
  std::vector<uint64_t> highlightPairs;   // texels compared with and without a light reflected
  std::vector<double> highlightContrast;  // their mean contrast
  std::vector<float> roughnessAtLeast;    // what the absence of a highlight bounds it by (-1: not tested)
  // Below which the absence also allows a lobe too sharp to have pointed at a light from the
  // frames' views (roughnessFromAbsence's sharpBelow; -1: it does not).
  std::vector<float> sharpBelow;
  std::vector<double> observedSum;        // luminance of the references seen in the emission stage
  std::vector<uint64_t> observedCount;

  explicit ObjectRoles(int objects);
  // To and from a fit's checkpoint (of `work`, named in errors); reading, sized for the objects
  // first, and refused when a value is none these fields can hold.
  void serialise(CheckpointIo& io, const std::filesystem::path& work);
};

// The scale of lights seen only saturated as config `c` sets it up.
ClippedLightSettings clippedLightSettings(const FitConfig& c);

class LightDecisions {
 public:
  // `gains`: the frames' (the evidence compares radiance, each frame's pixels divided by its gain).
  LightDecisions(const FitConfig& c, const Workspace& w, Appearance& a, ObjectRoles& roles, const PathSettings& path,
                 const FrameGains& gains)
      : c_(c), w_(w), a_(a), r_(roles), path_(path), gains_(gains) {}

  // An object no kept frame sees is no light-source candidate: nothing of its own radiance is
  // observed, so its emission trades off against the albedo of what it lights.
  void excludeUnseen(const TexelSpace& space);
  // The `lights` hint: exactly the objects it names are candidates, and they stay lights.
  void applyHint();
  // With light_albedo_zero, the light sources' texels take albedo 0.
  void zeroLightAlbedo(const TexelSpace& space);
  // Decides the light sources after stage `after` (`first`: the first decision). Returns whether
  // they changed, in which case the emission is refitted and the albedo's running fits restart.
  bool decide(const TexelSpace& space, const std::string& after, bool first);
  // Notes whether the lights include some seen only saturated (the scale probes run then).
  void findClippedLights(const TexelSpace& space);
  // Lights seen only saturated take the emission that makes each object's albedo most uniform
  // (clipped_light_scale.h), recorded with the decisions. Returns whether it changed them.
  bool scaleClippedLights(const TexelSpace& space, const std::string& after);
  // With clipped_light_silhouette_colour, after the last scale: each light it found seen only saturated
  // takes the colour its outline shows where that is known (silhouette_colour.h), at its luminance,
  // recorded with the decisions. Returns whether it changed some.
  bool colourClippedLights(const std::string& after);
  // Unobserved texels take their object's mean albedo (or 0.5 on an object no frame saw).
  void fillUnobservedAlbedo(const TexelSpace& space);
  // Which objects the frames show a highlight on. Probe connections either see a light reflected
  // or not (seesLightReflected); for each texel with connections of both kinds, contrast = mean
  // radiance seeing a light / mean radiance not - 1 (the same texel from other frames, so albedo
  // and irradiance cancel). Roughness and specular are fitted on objects whose mean contrast,
  // less two standard errors, reaches highlight_min_contrast over at least highlight_min_pairs
  // texels. On the other objects seen both ways often enough (highlight_absence), the absence of
  // a highlight bounds the roughness from below (roughnessFromAbsence: the roughnesses the fit
  // would render a brighter contrast at than the frames show are ruled out), and the roughness
  // takes the middle of what is left, the rough branch (a sharp branch below the ruled-out ones is
  // reported, sharpBelow); elsewhere they keep their init and are reported unconstrained.
  void decideHighlights(const TexelSpace& space, const FitBatches& batches);

  // The emission stage's references, per object (the radiance-fraction test compares with them).
  void observe(const Batch& batch);
  bool lightsDecided() const { return !c_.lights.empty() || !r_.lightDecisions.empty(); }
  // Per object: whether its albedo is held (light_albedo_zero, once the lights are decided).
  std::vector<uint8_t> albedoHeld() const;

 private:
  void prune();
  void restartAlbedo(const TexelSpace& space, const std::vector<LightEvidence>& evidence,
                     const std::vector<uint8_t>& dropped);

  const FitConfig& c_;
  const Workspace& w_;
  Appearance& a_;
  ObjectRoles& r_;
  const PathSettings& path_;
  const FrameGains& gains_;
  std::vector<int> clippedLights_;  // the lights the last scale found seen only saturated
};

}  // namespace relume
