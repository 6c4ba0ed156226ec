#include "product/confidence.h"

#include <algorithm>
#include <array>
#include <functional>

#include "core/check.h"
#include "core/error.h"
#include "io/image.h"

namespace relume {
namespace {

// The surfaces of the light sources, to tell texels beside one (BesideLights::near).
class BesideLights {
 public:
  BesideLights(const Workspace& w, const Appearance& a) : w_(w) {
    for (size_t f = 0; f < w.mesh.triangles.size(); ++f)
      if (a.isEmissive(w.mesh.faceObject[f])) {
        Eigen::AlignedBox3f box;
        for (int k = 0; k < 3; ++k) box.extend(w.mesh.positions[w.mesh.triangles[f][k]]);
        faces_.push_back({f, box});
      }
  }
  // Whether p lies within kMixedFootprints pixel footprints (at the median distance of the kept
  // frames' cameras) of a light source's surface: the pixels that see it mix in the light's
  // radiance (the pixel filter, the rays' bilinear lookup), so it looks brighter than any albedo
  // returns with no light missing (a halo around each ceiling panel).
  bool near(const Vec3& p) const {
    if (faces_.empty()) return false;
    std::vector<float> footprint;
    for (uint32_t k : w_.kept) footprint.push_back((p - w_.frames[k].camera.position).norm() / w_.frames[k].camera.fx);
    const float margin = kMixedFootprints * medianOf(std::move(footprint));
    for (const auto& [f, box] : faces_) {
      if (box.exteriorDistance(p) > margin) continue;
      const Eigen::Vector3i& v = w_.mesh.triangles[f];
      const std::vector<Vec3>& at = w_.mesh.positions;
      if ((p - closestPointOnTriangle(p, at[v[0]], at[v[1]], at[v[2]])).norm() <= margin) return true;
    }
    return false;
  }

 private:
  static constexpr float kMixedFootprints = 4;
  const Workspace& w_;
  std::vector<std::pair<size_t, Eigen::AlignedBox3f>> faces_;
};

// Of a texel's observed radiance `seen`, what albedo 1 under the fitted lights leaves unexplained:
// per channel seen (1 - 1/u), u its unbounded albedo where above 1.
Color missingRadiance(const float* unbounded, const Color& seen) {
  Color m = Color::Zero();
  for (int k = 0; k < 3; ++k)
    if (const float u = unbounded[k]; u > 1) m[k] = seen[k] * (1 - 1 / u);
  return m;
}

// Per object (and over all, at index `objects`): the observed radiance of its reflector texels,
// what the fitted lights leave unexplained of it, and where (the missing radiance times the point).
struct UnplacedTally {
  explicit UnplacedTally(int objects)
      : all(objects), seen(objects + 1, 0.0), missing(objects + 1, 0.0), at(objects + 1, Eigen::Vector3d::Zero()) {}
  void add(int o, double seenHere, double missingHere, const Vec3& point) {
    for (int i : {o, all}) {
      seen[i] += seenHere, missing[i] += missingHere;
      at[i] += missingHere * point.cast<double>();
    }
  }
  static double share(double part, double whole) { return whole > 0 ? part / whole : 0.0; }
  Json centre(int i) const {
    const Eigen::Vector3d c = at[i] / std::max(missing[i], 1e-300);
    return Json::array({c.x(), c.y(), c.z()});
  }
  // confidence.json's unplaced_light: overall, and the objects with some, largest first.
  Json toJson(const std::vector<std::string>& names) const {
    Json objects = Json::array();
    for (int o = 0; o < all; ++o)
      if (missing[o] > 0)
        objects.push_back({{"id", o},
                           {"name", names[o]},
                           {"share_of_observed", share(missing[o], seen[all])},
                           {"share_of_its_own", share(missing[o], seen[o])},
                           {"centre", centre(o)}});
    std::sort(objects.begin(), objects.end(), [](const Json& a, const Json& b) {
      return a.at("share_of_observed").get<double>() > b.at("share_of_observed").get<double>();
    });
    return {{"share_of_observed", share(missing[all], seen[all])}, {"centre", centre(all)}, {"objects", objects}};
  }

  int all;
  std::vector<double> seen, missing;  // luminance, summed over texels (of one area each)
  std::vector<Eigen::Vector3d> at;
};

Json materialEvidence(const ObjectRoles& roles, int o) {
  if (roles.highlight[o]) return "highlights";
  if (roles.roughnessAtLeast[o] < 0) return "none (kept at its prior)";
  Json bound = {{"roughness_at_least", roles.roughnessAtLeast[o]}};
  if (roles.sharpBelow[o] >= 0) bound["or_sharper_than"] = roles.sharpBelow[o];
  return {{"absence_of_highlights", bound}};
}

}  // namespace

const float* SettledAlbedo::unboundedBeyondOne(uint32_t t) const {
  const auto it = std::lower_bound(beyondOne.begin(), beyondOne.end(), t);
  if (it == beyondOne.end() || *it != t) return nullptr;
  return &beyondOneAlbedo[3 * static_cast<size_t>(it - beyondOne.begin())];
}

void SettledAlbedo::findBeyondOne(const GaussNewtonState& newton, size_t texels, float bound) {
  beyondOne.clear(), beyondOneAlbedo.clear();
  beyondOneKnown = newton.size() == 3 * texels;
  if (!beyondOneKnown) return;  // no Gauss-Newton fit of this albedo
  for (size_t t = 0; t < texels; ++t) {
    bool beyond = false;
    for (size_t i = 3 * t; i < 3 * t + 3; ++i) {
      const float u = newton.unbounded(i), se = newton.tracksSpread() ? newton.standardError(i, bound) : 0.0f;
      beyond |= u > 1 + kUnderLitExcess && se >= 0 && u - 1 > kUnderLitErrors * se;
    }
    if (!beyond) continue;
    beyondOne.push_back(static_cast<uint32_t>(t));
    for (size_t i = 3 * t; i < 3 * t + 3; ++i) beyondOneAlbedo.push_back(newton.unbounded(i));
  }
}

void SettledAlbedo::serialise(CheckpointIo& io, size_t texels, const std::filesystem::path& work) {
  if (io.optional("albedo.standard_error", !standardError.empty())) {
    if (!io.writing()) standardError.resize(3 * texels);
    io.arrayInPlace("albedo.standard_error", standardError);
  }
  beyondOneKnown = io.optional("albedo.beyond_one_count", beyondOneKnown);
  if (!beyondOneKnown) return;
  uint64_t count = beyondOne.size();
  io.single("albedo.beyond_one_count", count);
  if (!io.writing()) {
    if (count > texels)  // before the allocation it sizes
      fail("{}: checkpoint's albedo.beyond_one_count {} exceeds the albedo's {} texels", work.string(), count, texels);
    beyondOne.resize(count), beyondOneAlbedo.resize(3 * count);
  }
  io.array("albedo.beyond_one", beyondOne);
  io.array("albedo.beyond_one_albedo", beyondOneAlbedo);
  if (!std::is_sorted(beyondOne.begin(), beyondOne.end(), std::less_equal<>()) ||
      (!beyondOne.empty() && beyondOne.back() >= texels))
    fail("{}: checkpoint's albedo.beyond_one is not ascending texels of the albedo", work.string());
}

const char* texelEvidenceName(TexelEvidence e) {
  switch (e) {
    case TexelEvidence::Unseen: return "unseen";
    case TexelEvidence::Few: return "few";
    case TexelEvidence::Disagree: return "disagree";
    case TexelEvidence::UnderLit: return "under_lit";
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
      Color(0.2f, 0.9f, 0.95f),  // under-lit: cyan
      Color(1.0f, 0.6f, 0.1f),   // uncertain: orange
      Color(0.2f, 0.7f, 0.3f),   // measured: green
      Color(1.0f, 1.0f, 1.0f),   // light measured: white
      Color(0.4f, 0.65f, 1.0f),  // light saturated: light blue
  };
  return srgb[static_cast<size_t>(e)];
}

TexelConfidence texelConfidence(const Workspace& w, const TexelSpace& space, const Appearance& appearance,
                                const ObjectRoles& roles, const std::optional<Image>& agreement,
                                const SettledAlbedo& settled, const std::optional<Image>& median) {
  const int res = space.resolution, perInit = res / w.initResolution;
  CHECK(perInit >= 1 && res % w.initResolution == 0);
  if (agreement && (agreement->width != w.initResolution || agreement->height != w.initResolution))
    fail("{}: agreement.exr is {}x{}, expected {}^2", w.dir.string(), agreement->width, agreement->height,
         w.initResolution);
  const size_t texels = space.map.texelCount();
  CHECK(settled.standardError.empty() || settled.standardError.size() == 3 * texels);
  CHECK(!settled.beyondOneKnown || median);
  CHECK(settled.beyondOne.empty() || (settled.beyondOne.back() < texels &&
                                      settled.beyondOneAlbedo.size() == 3 * settled.beyondOne.size()));
  CHECK(!median || (median->width == w.initResolution && median->height == w.initResolution));
  TexelConfidence c;
  c.channels = Image(res, res);
  c.evidence.assign(texels, kOffSurface);
  const int objects = appearance.objectCount();
  std::vector<std::array<size_t, kTexelEvidenceKinds>> counts(objects + 1, std::array<size_t, kTexelEvidenceKinds>{});
  UnplacedTally unplaced(objects);
  const BesideLights lights(w, appearance);
  for (size_t t = 0; t < texels; ++t) {
    if (!space.map.covered(t)) continue;
    const int x = static_cast<int>(t % res), y = static_cast<int>(t / res);
    const int o = space.objectOf(t, w.mesh);
    const float observations = w.coverageOf(t, res);
    const Color agrees = agreement ? agreement->at(x / perInit, y / perInit) : Color::Zero();
    float error = 0;
    if (!settled.standardError.empty())
      for (size_t i = 3 * t; i < 3 * t + 3; ++i) error = std::max(error, settled.error(i));
    const float* beyondOne = settled.unboundedBeyondOne(static_cast<uint32_t>(t));
    TexelEvidence e = TexelEvidence::Measured;
    if (observations <= 0) e = TexelEvidence::Unseen;
    else if (appearance.isEmissive(o))
      e = agrees[2] >= kSaturatedShare ? TexelEvidence::LightSaturated : TexelEvidence::LightMeasured;
    else if (observations < kFewObservations) e = TexelEvidence::Few;
    else if (agrees[1] > kDisagreeShare) e = TexelEvidence::Disagree;
    else if (beyondOne && !lights.near(space.map.point(w.mesh, t))) e = TexelEvidence::UnderLit;
    else if (error > kUncertainAlbedo) e = TexelEvidence::Uncertain;
    if (median && observations > 0 && !appearance.isEmissive(o)) {
      const Color seen = median->at(x / perInit, y / perInit).max(0.0f);
      const double missing = e == TexelEvidence::UnderLit ? luminance(missingRadiance(beyondOne, seen)) : 0.0;
      unplaced.add(o, luminance(seen), missing, missing > 0 ? space.map.point(w.mesh, t) : Vec3::Zero());
    }
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
                 {"saturated_share", kSaturatedShare},
                 {"under_lit_excess", kUnderLitExcess},
                 {"under_lit_errors", kUnderLitErrors}}},
               {"agreement", agreement.has_value()},
               {"objects", perObject}};
  if (settled.beyondOneKnown) c.summary["unplaced_light"] = unplaced.toJson(appearance.names);
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
