#include "product/light_decisions.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>

#include "core/error.h"
#include "core/random_streams.h"
#include "core/rng.h"
#include "core/system.h"
#include "product/clipped_light_scale.h"
#include "product/silhouette_colour.h"
#include "render/bsdf.h"
#include "render/lights.h"
#include "render/path_tracer.h"
#include "sampling/highlight_evidence.h"
#include "sampling/samplers.h"

namespace relume {
namespace {
constexpr uint64_t kHighlightProbeBatches = 16;
// Unclipped rays a channel needs for their mean to stand for a light's emission (of the 256 or so
// interior rays drawn per object).
constexpr uint64_t kMinUnclippedRays = 16;
}  // namespace

ObjectRoles::ObjectRoles(int objects)
    : emitter(objects, 1),
      outOfModel(objects, 0),
      highlight(objects, 0),
      highlightPairs(objects, 0),
      highlightContrast(objects, 0.0),
      roughnessAtLeast(objects, -1.0f),
      sharpBelow(objects, -1.0f),
      observedSum(objects, 0.0),
      observedCount(objects, 0) {}

void ObjectRoles::serialise(CheckpointIo& io, const std::filesystem::path& work) {
  io.json("light_decisions", lightDecisions);
  io.array("emitter", emitter);
  io.array("out_of_model", outOfModel);
  io.single("refit_emission", refitEmission);
  io.single("clipped_lights", clippedLights);
  io.single("clipped_scale_moving", clippedScaleMoving);
  if (io.optional("clipped_scale_chose", true)) io.single("clipped_scale_chose", clippedScaleChose);  // older: none
  io.array("highlight", highlight);
  io.array("highlight_pairs", highlightPairs);
  io.array("highlight_contrast", highlightContrast);
  io.array("roughness_at_least", roughnessAtLeast);
  if (io.optional("sharp_below", true)) io.array("sharp_below", sharpBelow);  // older checkpoints: none
  io.array("observed.sum", observedSum);
  io.array("observed.count", observedCount);
  if (io.writing()) return;
  // What materials.json, confidence.json and the light decisions take from here as it is.
  const auto flag = [](uint8_t v) { return v <= 1; };
  const auto requireFlags = [&](const char* name, const std::vector<uint8_t>& flags) {
    if (!std::all_of(flags.begin(), flags.end(), flag))
      fail("{}: checkpoint's {} holds a value that is neither 0 nor 1", work.string(), name);
  };
  requireFlags("emitter", emitter), requireFlags("out_of_model", outOfModel), requireFlags("highlight", highlight);
  if (!flag(refitEmission) || !flag(clippedLights) || !flag(clippedScaleMoving) || !flag(clippedScaleChose))
    fail("{}: checkpoint's refit_emission, clipped_lights, clipped_scale_moving or clipped_scale_chose is neither 0 "
         "nor 1",
         work.string());
  const auto bound = [](float v) { return v == -1.0f || (v >= 0.0f && v <= 1.0f); };
  for (size_t o = 0; o < roughnessAtLeast.size(); ++o)
    if (!bound(roughnessAtLeast[o]) || !bound(sharpBelow[o]) || (roughnessAtLeast[o] < 0 && sharpBelow[o] >= 0))
      fail("{}: checkpoint's roughness_at_least / sharp_below of object {} ({}, {}) is no roughness bound (-1 or "
           "in [0, 1], sharp_below only with roughness_at_least)",
           work.string(), o, roughnessAtLeast[o], sharpBelow[o]);
  for (size_t o = 0; o < observedSum.size(); ++o)
    if (!std::isfinite(observedSum[o]))
      fail("{}: checkpoint's observed.sum of object {} is not finite", work.string(), o);
}

void LightDecisions::observe(const Batch& batch) {
  for (size_t j = 0; j < batch.rays.size(); ++j)
    r_.observedSum[batch.object[j]] += luminance(batch.rays[j].reference / batch.rays[j].gain),
        ++r_.observedCount[batch.object[j]];
}

std::vector<uint8_t> LightDecisions::albedoHeld() const {
  std::vector<uint8_t> held(r_.emitter.size(), 0);
  if (c_.lightAlbedoZero && lightsDecided())
    for (size_t o = 0; o < held.size(); ++o) held[o] = r_.emitter[o];
  return held;
}

// An object no kept frame sees is not a light-source candidate: nothing of its own radiance is
// observed, so its emission is constrained only by the light it throws on other surfaces, which
// trades off against their albedo. Fitted anyway, the 16-frame test room's never-seen painting
// came out a blue emitter in one seed of three, and relighting with the ceiling lights off lost 5 dB.
void LightDecisions::excludeUnseen(const TexelSpace& space) {
  std::vector<uint8_t> seen(a_.objectCount(), 0);
  for (uint32_t t : space.sampleable) seen[space.objectOf(t, w_.mesh)] = 1;
  for (int o = 0; o < a_.objectCount(); ++o)
    if (!seen[o]) {
      r_.emitter[o] = 0;
      spdlog::info("fit: object {} ({}) is seen by no frame: not a light-source candidate", o, a_.names[o]);
    }
}
// The `lights` hint: exactly the objects it names are light-source candidates, and they stay
// lights (no decision is taken).
void LightDecisions::applyHint() {
  if (c_.lights.empty()) return;
  std::vector<uint8_t> hinted(a_.objectCount(), 0);
  for (const std::string& name : c_.lights) {
    const auto it = std::find(a_.names.begin(), a_.names.end(), name);
    if (it == a_.names.end()) fail("fit config: 'lights' names '{}', which is no object of {}", name, w_.dir.string());
    hinted[it - a_.names.begin()] = 1;
  }
  for (int o = 0; o < a_.objectCount(); ++o) {
    if (hinted[o] && !r_.emitter[o])
      spdlog::warn("fit: object {} ({}) is named a light but no frame sees it: its emission stays 0", o, a_.names[o]);
    r_.emitter[o] = r_.emitter[o] && hinted[o];
  }
}
// Light sources show their radiance as emission alone (light_albedo_zero): albedo 0 on their texels.
void LightDecisions::zeroLightAlbedo(const TexelSpace& space) {
  if (!c_.lightAlbedoZero) return;
  for (size_t t = 0; t < space.map.texelCount(); ++t)
    if (space.map.valid(t) && r_.emitter[space.objectOf(t, w_.mesh)])
      std::fill_n(a_.albedo.rgb.begin() + 3 * static_cast<ptrdiff_t>(t), 3, 0.0f);
}
// The light sources, decided from the evidence of their own pixels (light_evidence.h). First
// (after the emission stage): among the emission stage's candidates, with the albedo still its
// init; again after the first albedo stage: among every object with texels, under the fitted
// albedo. An object that becomes a light starts from the emission its evidence implies, one that
// stops goes to 0, and either change makes the emission_refit stage run. Objects a mirror
// explains better than an emission (out of model) leave the emission and the albedo for good.
bool LightDecisions::decide(const TexelSpace& space, const std::string& after, bool first) {
  if (!c_.lights.empty()) return false;  // the user named them
  if (c_.lightTest == LightTest::RadianceFraction) {
    if (first) prune();
    return false;
  }
  const int objects = a_.objectCount();
  const std::vector<std::vector<uint32_t>> texels = space.sampleableByObject(w_.mesh, objects);
  std::vector<uint8_t> candidate(objects, 0);
  for (int o = 0; o < objects; ++o)
    candidate[o] = !texels[o].empty() && !r_.outOfModel[o] && (first ? r_.emitter[o] != 0 : true);
  // Each candidate's own texels, the same number for each, through their centres (point rays).
  const uint64_t stream = hashTuple({c_.seed, streamTag(RandomStream::LightDecision), r_.lightDecisions.size()});
  Batch batch;
  for (int o = 0; o < objects; ++o) {
    if (!candidate[o]) continue;
    const TextureSpaceSampler own(*w_.scene, space.map, texels[o], w_.vis, w_.trainingFrames());
    batch.append(own.sample(hashTuple({stream, static_cast<uint64_t>(o)}), 0,
                            {c_.lightEvidenceTexels, c_.framesPerTexel, RayFootprint::Point, 1}));
  }
  gains_.apply(batch.rays, batch.frame);
  // Each ray's camera, found by its origin (the sampler's rays start at the camera).
  std::map<std::array<float, 3>, const Camera*> byPosition;
  for (uint32_t k : w_.kept) {
    const Vec3& p = w_.frames[k].camera.position;
    byPosition.emplace(std::array<float, 3>{p.x(), p.y(), p.z()}, &w_.frames[k].camera);
  }
  std::vector<const Camera*> cameras(batch.rays.size());
  for (size_t j = 0; j < batch.rays.size(); ++j) {
    const Vec3& o = batch.rays[j].origin;
    const auto it = byPosition.find({o.x(), o.y(), o.z()});
    cameras[j] = it != byPosition.end() ? it->second : nullptr;
  }
  const LightSampler lights(*w_.scene, a_);
  const std::function<std::optional<Color>(size_t, const Vec2&)> framePixel = [&](size_t j, const Vec2& q) {
    return w_.store->bilinear(batch.frame[j], q);
  };
  std::vector<LightEvidence> evidence = gatherLightEvidence(*w_.scene, w_.mesh, a_, lights, batch.rays, batch.object,
                                                            path_, stream, &cameras, &framePixel);
  const LightTestSettings test{c_.lightMinUnexplained, c_.lightSignificance, c_.pruneFraction, c_.lightMinContrast,
                               c_.lightSaturatedFloor};
  const std::vector<LightDecision> decisions = decideLights(evidence, candidate, test, r_.emitter);
  // Under-lit surfaces are reported at the last decision only: before the albedo is fitted, the
  // init darkens the light every surface receives (the White Room: 12 under-lit reflectors after
  // the emission stage, none after the first albedo stage).
  const bool last = !first || !c_.lightRedecide;
  std::vector<uint8_t> dropped(objects, 0);
  bool changed = false;
  for (int o = 0; o < objects; ++o) {
    if (!candidate[o]) continue;
    const LightDecision& d = decisions[o];
    const bool light = d.verdict == LightVerdict::Light;
    spdlog::info("fit: after {}: object {} ({}) is {}: {}", after, o, a_.names[o], lightVerdictName(d.verdict), d.why);
    if (const UnderLit u = underLit(evidence[o], test); last && u.underLit && d.verdict == LightVerdict::Reflector)
      spdlog::warn(
          "fit: after {}: object {} ({}) is under-lit: {:.3g} of its radiance no light in view explains; the missing "
          "light "
          "lands around ({:.2f}, {:.2f}, {:.2f}) and comes from direction ({:.2f}, {:.2f}, {:.2f}) (a light seen only "
          "from "
          "behind, outside the frames or under a shade?)",
          after, o, a_.names[o], u.missing, u.centre[0], u.centre[1], u.centre[2], u.from[0], u.from[1], u.from[2]);
    if (d.verdict == LightVerdict::OutOfModel) r_.outOfModel[o] = 1;
    r_.emitter[o] = light;
    if (!light) {
      dropped[o] = !first && a_.isEmissive(o);
      a_.emission[o] = Color::Zero();
    } else {
      // A light's emission is set when it becomes one (and, with light_albedo_zero, at the
      // first decision, where its albedo goes to 0); a re-decision that agrees changes nothing.
      // It is what its pixels show; where they show only a lower bound (clipped above what its
      // unclipped pixels measure, or too few of those), the emission fitted from the light it
      // casts is kept when it is brighter.
      const bool wasEmitting = a_.isEmissive(o);
      if (c_.lightAlbedoZero && (first || !wasEmitting)) {
        const LightEvidence::PixelEmission shown =
            evidence[o].pixelEmission(kMinUnclippedRays, c_.lightUnclippedEmission);
        a_.emission[o] = shown.lowerBound ? Color(shown.emission.max(a_.emission[o])) : shown.emission;
      } else if (!wasEmitting)
        a_.emission[o] = evidence[o].emissionEstimate();
      changed |= !first && !wasEmitting;
    }
  }
  changed |= std::count(dropped.begin(), dropped.end(), 1) > 0;
  zeroLightAlbedo(space);
  if (changed) {
    r_.refitEmission = 1;
    restartAlbedo(space, evidence, dropped);
  }
  r_.lightDecisions.push_back(
      {{"after", after}, {"objects", lightDecisionsJson(evidence, decisions, a_.names, test, last)}});
  return changed;
}

ClippedLightSettings clippedLightSettings(const FitConfig& c) {
  return {.texelsPerObject = 4 * c.lightEvidenceTexels,
          .framesPerTexel = c.framesPerTexel,
          .pathsPerRay = c.clippedScalePaths,
          .shownRadiance = c.clippedScaleShownRadiance,
          .materialChoice = c.clippedScaleMaterialChoice,
          .albedoCeiling = c.clippedScaleAlbedoCeiling,
          .ceilingSigmas = c.lightSignificance};
}

void LightDecisions::findClippedLights(const TexelSpace& space) {
  const std::vector<int> lights =
      lightsSeenOnlySaturated(w_, space, a_, r_.emitter, gains_, clippedLightSettings(c_), c_.seed);
  r_.clippedLights = !lights.empty();
  for (int o : lights) spdlog::info("fit: light {} ({}) is seen only saturated", o, a_.names[o]);
}

bool LightDecisions::colourClippedLights(const std::string& after) {
  const std::vector<int>& lights = clippedLights_;
  if (lights.empty()) return false;
  bool changed = false;
  Json entries = Json::array();
  for (const SilhouetteColour& m : measureSilhouetteColours(w_, gains_, lights, a_.emission, r_.emitter)) {
    const Color before = a_.emission[m.light];
    if (m.known) a_.emission[m.light] = m.colour * luminance(before), changed = true;
    const Color& e = a_.emission[m.light];
    if (!m.measured)
      spdlog::info("fit: after {}: light {} ({}): its outline has too few unclipped pixels to show its colour ({} in "
                   "{} frames); its colour kept",
                   after, m.light, a_.names[m.light], m.pixels, m.frames);
    else
      spdlog::info("fit: after {}: light {} ({}): its outline shows the colour {:.3f} {:.3f} {:.3f} (log error {:.3f} "
                   "{:.3f} {:.3f}; {} pixels in {} frames){}",
                   after, m.light, a_.names[m.light], m.colour[0], m.colour[1], m.colour[2], m.logError[0],
                   m.logError[1], m.logError[2], m.pixels, m.frames,
                   m.known ? fmt::format(": emission {:.3g} {:.3g} {:.3g} -> {:.3g} {:.3g} {:.3g}", before[0],
                                         before[1], before[2], e[0], e[1], e[2])
                           : std::string(": not known well enough, its colour kept"));
    Json entry = m.toJson();
    entry["id"] = m.light;
    entry["name"] = a_.names[m.light];
    entries.push_back(std::move(entry));
  }
  r_.lightDecisions.push_back({{"after", after}, {"silhouette_colour", entries}});
  return changed;
}

bool LightDecisions::scaleClippedLights(const TexelSpace& space, const std::string& after) {
  const ClippedLightScale scale = relume::scaleClippedLights(w_, space, a_, r_.emitter, r_.outOfModel, gains_, path_,
                                                             clippedLightSettings(c_), c_.seed);
  clippedLights_ = scale.lights;
  if (scale.lights.empty()) return false;
  if (scale.applied)
    spdlog::info("fit: after {}: {}", after, scale.why);
  else
    spdlog::warn("fit: after {}: {}", after, scale.why);
  std::string perObject;
  for (const auto& [o, s] : scale.fit.perObject) {
    // NaN: the object's own scale lies on the grid's edge (its texels do not tell it).
    perObject += std::isfinite(s) ? fmt::format(" {} {:.3g}", a_.names[o], s) : fmt::format(" {} none", a_.names[o]);
    if (const int h = scale.firstVertexMaterial.empty() ? 0 : scale.firstVertexMaterial[o]; h > 0)
      perObject += fmt::format(" (as roughness {:.2g}, specular {:.2g})", kFirstVertexMaterials[h - 1].roughness,
                               kFirstVertexMaterials[h - 1].specular);
    perObject += ";";
  }
  spdlog::info("fit: after {}: each object's most uniform scale:{}{}", after, perObject,
               scale.materialsDeferred ? " (under the fit's materials: the choice waits until that scale settles)" : "");
  Json entry = {{"after", after}, {"clipped_light_scale", scale.toJson(a_)}};
  r_.lightDecisions.push_back(std::move(entry));
  // The first scale under the chosen materials always has a successor: the albedo it started from
  // had followed the scale under the fit's own (on the bracketed room it stopped there 6-7% short).
  const bool firstChoice = !scale.firstVertexMaterial.empty() && !r_.clippedScaleChose;
  r_.clippedScaleMoving = scale.movesLights() || (scale.applied && firstChoice);
  r_.clippedScaleChose |= !scale.firstVertexMaterial.empty();
  return scale.applied;
}

// Texels no frame saw are never updated; they light the rest of the scene all the same (a
// capture that faces one way leaves most of a room unseen: 78% of the White Room's texels). They
// take their object's mean albedo over its observed texels, or 0.5 on an object no frame saw,
// instead of the init's radiance-scaled guess (an unseen wall's mean radiance x the white-point
// scale: 0.07 for a wall of albedo 0.6 there, which darkens the light every surface receives).
void LightDecisions::fillUnobservedAlbedo(const TexelSpace& space) {
  const int objects = a_.objectCount();
  std::vector<Eigen::Array4d> mean(objects, Eigen::Array4d::Zero());
  const std::vector<float>& a = a_.albedo.rgb;
  for (uint32_t t : space.sampleable)
    mean[space.objectOf(t, w_.mesh)] += Eigen::Array4d(a[3 * t], a[3 * t + 1], a[3 * t + 2], 1.0);
  size_t filled = 0;
  for (size_t t = 0; t < space.map.texelCount(); ++t) {
    if (!space.map.valid(t) || space.updatable[t] || r_.outOfModel[space.objectOf(t, w_.mesh)]) continue;
    const Eigen::Array4d& m = mean[space.objectOf(t, w_.mesh)];
    const Color fill = m[3] > 0 ? Color((m.head<3>() / m[3]).cast<float>()) : Color::Constant(0.5f);
    for (int c = 0; c < 3; ++c) a_.albedo.rgb[3 * t + c] = fill[c];
    ++filled;
  }
  spdlog::debug("fit: {} unobserved texels take their object's mean albedo", filled);
}
// The lights changed, so every albedo was fitted under the wrong light: the running fits start
// over (their averages hold residuals of the old lights; the caller restarts the optimiser), and
// an object that stopped being a light, whose albedo had collapsed while its emission made up its radiance, is rescaled
// to the albedo its evidence implies (what it shows over what albedo 1 returns).
void LightDecisions::restartAlbedo(const TexelSpace& space, const std::vector<LightEvidence>& evidence,
                                   const std::vector<uint8_t>& dropped) {
  const int objects = a_.objectCount();
  std::vector<Eigen::Array3d> sum(objects, Eigen::Array3d::Zero());
  std::vector<size_t> count(objects, 0);
  for (uint32_t t : space.sampleable) {
    const int o = space.objectOf(t, w_.mesh);
    if (!dropped[o]) continue;
    sum[o] += Eigen::Array3d(a_.albedo.rgb[3 * t], a_.albedo.rgb[3 * t + 1], a_.albedo.rgb[3 * t + 2]);
    ++count[o];
  }
  // Each channel scaled so that its mean is the estimate; set to it where the albedo is ~0 (held
  // at 0 while the object was a light).
  std::vector<Color> target(objects, Color::Zero()), scale(objects, Color::Zero());
  for (int o = 0; o < objects; ++o)
    if (dropped[o] && count[o] > 0) {
      target[o] = evidence[o].albedoEstimate();
      for (int c = 0; c < 3; ++c)
        scale[o][c] = sum[o][c] > 1e-3 * count[o] ? static_cast<float>(target[o][c] * count[o] / sum[o][c]) : 0.0f;
      spdlog::info("fit: object {} ({}) is no light: its albedo restarts at {:.3g} {:.3g} {:.3g}", o, a_.names[o],
                   target[o][0], target[o][1], target[o][2]);
    }
  for (size_t t = 0; t < space.map.texelCount(); ++t) {
    if (!space.map.valid(t)) continue;
    const int o = space.objectOf(t, w_.mesh);
    if (!dropped[o] || count[o] == 0) continue;
    for (int c = 0; c < 3; ++c) {
      float& a = a_.albedo.rgb[3 * t + c];
      a = std::clamp(scale[o][c] > 0 ? a * scale[o][c] : target[o][c], 0.0f, 1.0f);
    }
  }
}
// light_test radiance_fraction: light sources are the objects whose own emission explains most of how they look (at
// least r_.emitterradiance_fraction of their mean observed radiance) and that carry at least prune_fraction of the
// total emitted power. The rest go to 0 and stay frozen. The radiance test matters because during this stage the albedo
// is the median radiance, darker than the true albedo by the irradiance factor, so lit walls make up for it with a weak
// emission of their own.
void LightDecisions::prune() {
  std::vector<double> area(a_.objectCount(), 0.0);
  for (size_t f = 0; f < w_.mesh.triangles.size(); ++f) {
    const auto& t = w_.mesh.triangles[f];
    area[w_.mesh.faceObject[f]] += 0.5 * (w_.mesh.positions[t[1]] - w_.mesh.positions[t[0]])
                                             .cross(w_.mesh.positions[t[2]] - w_.mesh.positions[t[0]])
                                             .norm();
  }
  std::vector<double> power(a_.objectCount());
  double totalPower = 0;
  for (int o = 0; o < a_.objectCount(); ++o) totalPower += power[o] = luminance(a_.emission[o]) * area[o];
  for (int o = 0; o < a_.objectCount(); ++o) {
    const double observed = r_.observedCount[o] ? r_.observedSum[o] / r_.observedCount[o] : 0.0;
    r_.emitter[o] = r_.emitter[o] && totalPower > 0 && power[o] >= c_.pruneFraction * totalPower &&
                    luminance(a_.emission[o]) >= c_.emitterRadianceFraction * observed;
    if (power[o] >= c_.pruneFraction * totalPower && !r_.emitter[o])
      spdlog::info("fit: object {} ({}) emits {:.3g} but looks {:.3g}: lit, not a light source", o, a_.names[o],
                   luminance(a_.emission[o]), observed);
    if (!r_.emitter[o])
      a_.emission[o] = Color::Zero();
    else
      spdlog::info("fit: object {} ({}) is a light source: emission {:.3g} {:.3g} {:.3g}, {:.1f}% of the power", o,
                   a_.names[o], a_.emission[o][0], a_.emission[o][1], a_.emission[o][2], 100 * power[o] / totalPower);
  }
}

namespace {
// The roughnesses the absence of a highlight is tested at (roughnessFromAbsence), and the lobe
// samples each connection draws at every one of them.
constexpr std::array<float, 10> kAbsenceRoughness = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.7f, 0.8f, 0.9f, 1.0f};
constexpr int kAbsenceLobeSamples = 16;

// The light a connection's first surface reflects straight from the light sources through its
// specular lobe alone, at each roughness of kAbsenceRoughness and the fit's specular: the lobe's
// own samples (f cos / pdf stays near the Fresnel factor at any roughness), each counting the
// emission it reaches, the same random numbers at every roughness. It is what a highlight adds to
// the texel's radiance; its diffuse radiance, the same from every view, cancels in the contrast.
std::array<float, kAbsenceRoughness.size()> directSpecular(const Scene& scene, const Appearance& a,
                                                           const BatchRay& ray, uint64_t stream) {
  std::array<float, kAbsenceRoughness.size()> out{};
  const auto hit = scene.intersect(ray.origin, ray.dir);
  if (!hit) return out;
  const ShadingFrame frame(hit->ng.dot(ray.dir) < 0.0f ? hit->ns : Vec3(-hit->ns));
  const Vec3 wo = frame.toLocal(-ray.dir);
  for (size_t r = 0; r < kAbsenceRoughness.size(); ++r) {
    const VertexBsdf lobe({Color::Zero(), kAbsenceRoughness[r], a.specular[hit->object], a.model}, wo);
    Pcg32 rng(stream);
    Color sum = Color::Zero();
    for (int k = 0; k < kAbsenceLobeSamples; ++k) {
      const float uLobe = rng.next1D();
      const auto bs = lobe.sample(uLobe, rng.next2D());
      if (!bs) continue;
      const Vec3 d = frame.toWorld(bs->wi);
      if (const auto light = scene.intersect(Scene::offsetOrigin(*hit, d), d))
        sum += bs->weight * emittedRadiance(a, *light, d);
    }
    out[r] = luminance(sum) / kAbsenceLobeSamples;
  }
  return out;
}

// Per connection of `batch` on a texel seen both with a light reflected and without, at each
// roughness of kAbsenceRoughness: the frames' mean radiance over the texel's connections without
// a light reflected, plus what the highlight adds (directSpecular). Their contrast is then what
// the fit's highlight would add over what the frames show, (S with - S without) / (shown without
// + S without), on the same connections as the frames' contrast. The same random numbers at every
// roughness. The other connections are marked -1 in `counted`.
std::vector<std::array<float, kAbsenceRoughness.size()>> renderAtEachRoughness(const Scene& scene, const Appearance& a,
                                                                              const Batch& batch,
                                                                              const std::vector<int8_t>& sawLight,
                                                                              const std::vector<float>& observed,
                                                                              std::vector<int8_t>& counted,
                                                                              uint64_t stream) {
  constexpr size_t K = kAbsenceRoughness.size();
  const size_t n = batch.rays.size();
  counted = sawLight;
  std::vector<float> shownWithout(n, 0.0f);
  for (size_t begin = 0, end = 0; begin < n; begin = end) {
    double shown = 0;
    int count[2] = {0, 0};
    for (end = begin; end < n && batch.slot[end] == batch.slot[begin]; ++end)
      if (sawLight[end] >= 0) {
        ++count[sawLight[end]];
        if (sawLight[end] == 0) shown += observed[end];
      }
    if (count[0] && count[1])
      std::fill(shownWithout.begin() + begin, shownWithout.begin() + end, static_cast<float>(shown / count[0]));
    else
      std::fill(counted.begin() + begin, counted.begin() + end, int8_t{-1});
  }
  std::vector<std::array<float, K>> lum(n);
  tbb::parallel_for(size_t{0}, n, [&](size_t j) {
    if (counted[j] < 0) return;
    lum[j] = directSpecular(scene, a, batch.rays[j], hashTuple({stream, static_cast<uint64_t>(j)}));
    for (float& v : lum[j]) v += shownWithout[j];
  });
  return lum;
}
}  // namespace

void LightDecisions::decideHighlights(const TexelSpace& space, const FitBatches& batches) {
  const Timer timer;
  const int objects = a_.objectCount();
  HighlightEvidence evidence(objects);
  // What the fit renders on the same connections at each tested roughness (highlight_absence).
  std::vector<HighlightEvidence> rendered;
  if (c_.highlightAbsence) rendered.assign(kAbsenceRoughness.size(), HighlightEvidence(objects));
  for (uint64_t probe = 0; probe < kHighlightProbeBatches; ++probe) {
    Batch batch = batches.sample(space, (uint64_t{1} << 40) + probe, c_.rayFootprint);
    gains_.apply(batch.rays, batch.frame);
    std::vector<int8_t> sawLight(batch.rays.size(), -1);
    std::vector<float> lum(batch.rays.size(), 0.0f);
    tbb::parallel_for(size_t{0}, batch.rays.size(), [&](size_t j) {
      sawLight[j] = seesLightReflected(*w_.scene, a_, r_.emitter, batch.rays[j]);
      if (sawLight[j] >= 0) lum[j] = luminance(batch.rays[j].reference / batch.rays[j].gain);
    });
    evidence.addBatch(batch.slot, batch.object, lum, sawLight);
    if (!c_.highlightAbsence) continue;
    std::vector<int8_t> counted;
    const uint64_t stream = hashTuple({c_.seed, streamTag(RandomStream::HighlightAbsence), probe});
    const auto atEach = renderAtEachRoughness(*w_.scene, a_, batch, sawLight, lum, counted, stream);
    std::vector<float> atRoughness(lum.size());
    for (size_t k = 0; k < kAbsenceRoughness.size(); ++k) {
      for (size_t j = 0; j < lum.size(); ++j) atRoughness[j] = atEach[j][k];
      rendered[k].addBatch(batch.slot, batch.object, atRoughness, counted);
    }
  }
  for (int o = 0; o < objects; ++o) {
    r_.highlightPairs[o] = evidence.texels(o), r_.highlightContrast[o] = evidence.contrast(o);
    r_.highlight[o] = !r_.emitter[o] && evidence.observed(o, c_.highlightMinPairs, c_.highlightMinContrast);
    std::string outcome = r_.highlight[o] ? "roughness/specular fitted" : "roughness/specular unconstrained (kept at init)";
    r_.roughnessAtLeast[o] = -1, r_.sharpBelow[o] = -1;
    if (c_.highlightAbsence && !r_.highlight[o] && !r_.emitter[o] && !r_.outOfModel[o] &&
        evidence.texels(o) >= static_cast<uint64_t>(c_.highlightMinPairs)) {
      std::array<double, kAbsenceRoughness.size()> contrast{}, error{};
      for (size_t k = 0; k < kAbsenceRoughness.size(); ++k)
        contrast[k] = rendered[k].contrast(o), error[k] = rendered[k].standardError(o);
      const RoughnessFromAbsence r =
          roughnessFromAbsence(evidence.contrast(o), evidence.standardError(o), kAbsenceRoughness, contrast, error);
      std::string curve;
      for (size_t k = 0; k < kAbsenceRoughness.size(); ++k)
        curve += fmt::format(" {:.1f}: {:+.1f}% +- {:.1f}%;", kAbsenceRoughness[k], 100 * contrast[k], 100 * error[k]);
      spdlog::debug("fit: object {} ({}) rendered at each roughness:{}", o, a_.names[o], curve);
      r_.roughnessAtLeast[o] = r.atLeast, r_.sharpBelow[o] = r.sharpBelow;
      a_.roughness[o] = r.chosen;
      outcome = r.roughestRuledOut
                    ? fmt::format("roughness 1: even the roughest renders {:+.1f}% at specular {:.2f}",
                                  100 * contrast.back(), a_.specular[o])
                    : fmt::format("roughness {:.2f}: a smoother lobe would have shown a highlight, ruled out below "
                                  "{:.1f} at specular {:.2f} (rendered {:+.1f}% there, {:+.1f}% at {:.1f}){}",
                                  r.chosen, r.atLeast, a_.specular[o],
                                  100 * contrast[std::find(kAbsenceRoughness.begin(), kAbsenceRoughness.end(),
                                                           r.atLeast) - kAbsenceRoughness.begin()],
                                  100 * contrast.front(), kAbsenceRoughness.front(),
                                  r.sharpBranch() ? fmt::format("; or a lobe sharper than {:.2f}, which never pointed "
                                                                "at a light from the frames' views",
                                                                r.sharpBelow)
                                                  : "");
    }
    spdlog::info(
        "fit: object {} ({}): {} texels seen with and without a light reflected, {:+.1f}% +- {:.1f}% brighter with it "
        "-> {}",
        o, a_.names[o], evidence.texels(o), 100 * evidence.contrast(o), 100 * evidence.standardError(o), outcome);
  }
  spdlog::info("fit: highlight test: {} objects fitted, {} bounded by the absence of one, in {:.1f} s",
               std::count(r_.highlight.begin(), r_.highlight.end(), 1),
               std::count_if(r_.roughnessAtLeast.begin(), r_.roughnessAtLeast.end(), [](float r) { return r >= 0; }),
               timer.seconds());
}

}  // namespace relume
