// Where the reconstruction rests on what the frames showed and where it is guessed, per texel of the
// fitted albedo (result/confidence.exr, .png, .json). A texel's evidence is the first of these that
// applies:
//   unseen            no kept frame saw it: its albedo is its object's mean (prepare's init);
//   few               seen fewer than kFewObservations times;
//   disagree          more than kDisagreeShare of its unclipped observations lie beyond prepare's
//                     kAgreementRatio of their median (agreement.exr): the mesh is not where the
//                     frames saw the surface (a misregistered edge, an object the mesh lacks), or a
//                     highlight;
//   uncertain         its albedo's standard error exceeds kUncertainAlbedo in a channel;
//   measured          none of the above;
// and on light sources, whose albedo is not fitted:
//   light measured    the frames show its emission unclipped;
//   light saturated   at least kSaturatedShare of its observations clip: its emission is inferred
//                     from the light it casts (docs/design/light-sources.md).
// Per object, what its roughness and specular rest on: the highlights the frames showed, the
// absence of any where one would have shown (a lower bound on the roughness), or neither (kept).
#pragma once
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "io/image.h"
#include "io/json.h"
#include "product/fit_workspace.h"
#include "product/light_decisions.h"
#include "scene/appearance.h"

namespace relume {

enum class TexelEvidence : uint8_t { Unseen, Few, Disagree, Uncertain, Measured, LightMeasured, LightSaturated };
inline constexpr int kTexelEvidenceKinds = 7;
inline constexpr uint8_t kOffSurface = 255;  // TexelConfidence::evidence of a texel off the surface
const char* texelEvidenceName(TexelEvidence e);

// An observation disagrees with its texel beyond this factor of the texel's median (prepare's
// agreement.exr).
inline constexpr float kAgreementRatio = 1.5f;
inline constexpr float kFewObservations = 5;   // eval scores the albedo from this many on

// How far an observation is from its texel's median `m`: the largest over channels of
// |log((c + e) / (m + e))|, e a tenth of m's luminance, so that colour counts (a red sofa before a
// brown floor of its brightness) and a channel far darker than the others does not turn its noise
// into disagreement. It disagrees beyond log(kAgreementRatio).
inline float observationDeviation(const Color& observed, const Color& median) {
  const float e = std::max(0.1f * luminance(median), 1e-12f);
  return ((observed.max(0.0f) + e) / (median.max(0.0f) + e)).log().abs().maxCoeff();
}
inline constexpr float kDisagreeShare = 0.25f;
inline constexpr float kUncertainAlbedo = 0.05f;
inline constexpr float kSaturatedShare = 0.95f;  // as clipped_light_scale's "seen only saturated"

struct TexelConfidence {
  // Per texel at the albedo's resolution: R observations, G the albedo's largest standard error
  // (1 where unknown, 0 with none computed), B the share of observations that disagree; 0 off the
  // surface.
  Image channels;
  std::vector<uint8_t> evidence;  // per texel a TexelEvidence, or kOffSurface
  Json summary;                   // shares of each kind by texel count, overall and per object
};

// `agreement`: prepare's agreement.exr (init resolution; absent from older work folders, and then
// nothing counts as disagreeing); `albedoError` the fit's per entry (empty: none).
TexelConfidence texelConfidence(const Workspace& w, const TexelSpace& space, const Appearance& appearance,
                                const ObjectRoles& roles, const std::optional<Image>& agreement,
                                std::span<const float> albedoError);

// One colour per kind (the report's legend gives them): black off the surface.
Image confidencePicture(const TexelConfidence& c, int resolution);
Color texelEvidenceColour(TexelEvidence e);  // sRGB in [0, 1] (the picture stores it linear)

}  // namespace relume
