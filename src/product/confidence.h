// Where the reconstruction rests on what the frames showed and where it is guessed, per texel of the
// fitted albedo (result/confidence.exr, .png, .json). A texel's evidence is the first of these that
// applies:
//   unseen            no kept frame saw it: its albedo is its object's mean (prepare's init);
//   few               seen fewer than kFewObservations times;
//   disagree          more than kDisagreeShare of its unclipped observations lie beyond prepare's
//                     kAgreementRatio of their median (agreement.exr): the mesh is not where the
//                     frames saw the surface (a misregistered edge, an object the mesh lacks), or a
//                     highlight;
//   under-lit         the frames show more than it could return with albedo 1 under the fitted lights
//                     (the albedo fit without its bounds exceeds 1 by kUnderLitExcess and by
//                     kUnderLitErrors standard errors in some channel), and not within four
//                     pixel footprints of a light source (whose radiance the pixels there mix
//                     in): lit by light no light source of the fit supplies (a lamp seen only
//                     from behind, a window outside every frame); its albedo is too bright and the
//                     missing light is not in the scene, so a relit render lacks it;
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
#include "optim/gauss_newton.h"
#include "io/json.h"
#include "product/fit_checkpoint.h"
#include "product/fit_workspace.h"
#include "product/light_decisions.h"
#include "scene/appearance.h"

namespace relume {

enum class TexelEvidence : uint8_t {
  Unseen,
  Few,
  Disagree,
  UnderLit,
  Uncertain,
  Measured,
  LightMeasured,
  LightSaturated
};
inline constexpr int kTexelEvidenceKinds = 8;
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
inline constexpr float kUnderLitExcess = 0.05f;
inline constexpr float kUnderLitErrors = 3.0f;
// From this share of the observed radiance on, the fit warns of light it cannot place and the
// report says so. Measured (docs/notes/2026-11-27-lights-no-frame-shows.md): clean captures
// 0.00002 (room) and 0.001 (lounge), one light in no frame 0.021 and 0.023.
inline constexpr double kUnplacedLightNotice = 0.005;

// What the settled albedo fit knows beyond the albedo's values.
struct SettledAlbedo {
  std::vector<float> standardError;  // per entry (3 per texel), negative where unknown; empty: none
  // The texels whose least-squares albedo without the [0, 1] bounds exceeds 1 by kUnderLitExcess
  // and kUnderLitErrors of its standard error (before albedo_smoothing, which lowers the albedo's)
  // in some channel, ascending, with that unbounded albedo (3 per texel). A few percent of the
  // texels at most, where a full texture of each would cost 400 MB at 4K.
  // `beyondOneKnown` false: not computed (the albedo stepped by Adam, or a fit before it existed).
  bool beyondOneKnown = false;
  std::vector<uint32_t> beyondOne;
  std::vector<float> beyondOneAlbedo;

  // Entry i's standard error, 1 (the albedo's whole range) where it is unknown.
  float error(size_t i) const { return standardError[i] < 0 ? 1.0f : standardError[i]; }
  // Texel t's unbounded albedo when it is among beyondOne, else nullptr.
  const float* unboundedBeyondOne(uint32_t t) const;
  // beyondOne from the albedo's Gauss-Newton state (its unbounded values and standard errors,
  // the latter at most `bound`); `texels` its entries' texel count.
  void findBeyondOne(const GaussNewtonState& newton, size_t texels, float bound);
  // To and from a fit's checkpoint (of `work`, named in errors), for an albedo of `texels` texels;
  // a checkpoint without them reads as not computed.
  void serialise(CheckpointIo& io, size_t texels, const std::filesystem::path& work);
};

struct TexelConfidence {
  // Per texel at the albedo's resolution: R observations, G the albedo's largest standard error
  // (1 where unknown, 0 with none computed), B the share of observations that disagree; 0 off the
  // surface.
  Image channels;
  std::vector<uint8_t> evidence;  // per texel a TexelEvidence, or kOffSurface
  // Shares of each kind by texel count, overall and per object, and the light no light source
  // supplies: per under-lit texel 1 - 1/u of its observed radiance (u the luminance of its
  // unbounded albedo), summed over texels (of one area each) as a share of all the reflectors'
  // observed radiance (prepare's median per texel), with the centre of where it falls (the mean
  // of the texels' points weighted by it). It is a lower bound: the missing light is counted only
  // where it lifts a texel beyond what albedo 1 returns.
  Json summary;
};

// `agreement`: prepare's agreement.exr (init resolution; absent from older work folders, and then
// nothing counts as disagreeing); `median`: prepare's median radiance (init resolution; needed
// when `settled.beyondOneKnown`).
TexelConfidence texelConfidence(const Workspace& w, const TexelSpace& space, const Appearance& appearance,
                                const ObjectRoles& roles, const std::optional<Image>& agreement,
                                const SettledAlbedo& settled, const std::optional<Image>& median);

// One colour per kind (the report's legend gives them): black off the surface.
Image confidencePicture(const TexelConfidence& c, int resolution);
Color texelEvidenceColour(TexelEvidence e);  // sRGB in [0, 1] (the picture stores it linear)

}  // namespace relume
