#include "product/confidence.h"

#include <array>

#include "core/check.h"
#include "core/error.h"
#include "io/image.h"

namespace relume {
namespace {

Json materialEvidence(const ObjectRoles& roles, int o) {
  if (roles.highlight[o]) return "highlights";
  if (roles.roughnessAtLeast[o] >= 0)
    return {{"absence_of_highlights", {{"roughness_at_least", roles.roughnessAtLeast[o]}}}};
  return "none (kept at its prior)";
}

}  // namespace

const char* texelEvidenceName(TexelEvidence e) {
  switch (e) {
    case TexelEvidence::Unseen: return "unseen";
    case TexelEvidence::Few: return "few";
    case TexelEvidence::Disagree: return "disagree";
    case TexelEvidence::Uncertain: return "uncertain";
    case TexelEvidence::Measured: return "measured";
    case TexelEvidence::LightMeasured: return "light_measured";
    case TexelEvidence::LightSaturated: return "light_saturated";
  }
  return "?";
}

Color texelEvidenceColour(TexelEvidence e) {
  static const std::array<Color, kTexelEvidenceKinds> srgb = {
      Color(0.3f, 0.3f, 0.3f),   // unseen: grey
      Color(0.85f, 0.1f, 0.1f),  // few: red
      Color(0.8f, 0.2f, 0.85f),  // disagree: magenta
      Color(1.0f, 0.6f, 0.1f),   // uncertain: orange
      Color(0.2f, 0.7f, 0.3f),   // measured: green
      Color(1.0f, 1.0f, 1.0f),   // light measured: white
      Color(0.4f, 0.65f, 1.0f),  // light saturated: light blue
  };
  return srgb[static_cast<size_t>(e)];
}

TexelConfidence texelConfidence(const Workspace& w, const TexelSpace& space, const Appearance& appearance,
                                const ObjectRoles& roles, const std::optional<Image>& agreement,
                                std::span<const float> albedoError) {
  const int res = space.resolution, perInit = res / w.initResolution;
  CHECK(perInit >= 1 && res % w.initResolution == 0);
  if (agreement && (agreement->width != w.initResolution || agreement->height != w.initResolution))
    fail("{}: agreement.exr is {}x{}, expected {}^2", w.dir.string(), agreement->width, agreement->height,
         w.initResolution);
  const size_t texels = space.map.texelCount();
  CHECK(albedoError.empty() || albedoError.size() == 3 * texels);
  TexelConfidence c;
  c.channels = Image(res, res);
  c.evidence.assign(texels, kOffSurface);
  const int objects = appearance.objectCount();
  std::vector<std::array<size_t, kTexelEvidenceKinds>> counts(objects + 1, std::array<size_t, kTexelEvidenceKinds>{});
  for (size_t t = 0; t < texels; ++t) {
    if (!space.map.covered(t)) continue;
    const int x = static_cast<int>(t % res), y = static_cast<int>(t / res);
    const int o = space.objectOf(t, w.mesh);
    const float observations = w.coverageOf(t, res);
    const Color agrees = agreement ? agreement->at(x / perInit, y / perInit) : Color::Zero();
    float error = 0;
    if (!albedoError.empty())
      for (int k = 0; k < 3; ++k) error = std::max(error, albedoError[3 * t + k] < 0 ? 1.0f : albedoError[3 * t + k]);
    TexelEvidence e = TexelEvidence::Measured;
    if (observations <= 0) e = TexelEvidence::Unseen;
    else if (appearance.isEmissive(o))
      e = agrees[2] >= kSaturatedShare ? TexelEvidence::LightSaturated : TexelEvidence::LightMeasured;
    else if (observations < kFewObservations) e = TexelEvidence::Few;
    else if (agrees[1] > kDisagreeShare) e = TexelEvidence::Disagree;
    else if (error > kUncertainAlbedo) e = TexelEvidence::Uncertain;
    c.evidence[t] = static_cast<uint8_t>(e);
    c.channels.set(x, y, Color(observations, error, agrees[1]));
    ++counts[o][static_cast<size_t>(e)], ++counts[objects][static_cast<size_t>(e)];
  }
  const auto shares = [](const std::array<size_t, kTexelEvidenceKinds>& n) {
    size_t total = 0;
    for (size_t k : n) total += k;
    Json j = {{"texels", total}};
    for (int k = 0; k < kTexelEvidenceKinds; ++k)
      if (n[k]) j[texelEvidenceName(static_cast<TexelEvidence>(k))] = static_cast<double>(n[k]) / total;
    return j;
  };
  Json perObject = Json::array();
  for (int o = 0; o < objects; ++o) {
    Json row = shares(counts[o]);
    row["id"] = o, row["name"] = appearance.names[o];
    if (!appearance.isEmissive(o)) row["materials_from"] = materialEvidence(roles, o);
    perObject.push_back(row);
  }
  c.summary = {{"all", shares(counts[objects])},
               {"thresholds",
                {{"agreement_ratio", kAgreementRatio},
                 {"few_observations", kFewObservations},
                 {"disagree_share", kDisagreeShare},
                 {"uncertain_albedo", kUncertainAlbedo},
                 {"saturated_share", kSaturatedShare}}},
               {"agreement", agreement.has_value()},
               {"objects", perObject}};
  return c;
}

Image confidencePicture(const TexelConfidence& c, int resolution) {
  Image out(resolution, resolution);
  for (size_t t = 0; t < c.evidence.size(); ++t)
    if (c.evidence[t] != kOffSurface) {
      const Color s = texelEvidenceColour(static_cast<TexelEvidence>(c.evidence[t]));
      out.set(static_cast<int>(t % resolution), static_cast<int>(t / resolution),
              Color(srgbToLinear(s[0]), srgbToLinear(s[1]), srgbToLinear(s[2])));
    }
  return out;
}

}  // namespace relume
