#include "product/light_evidence.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <cmath>

#include "adjoint/solver.h"
#include "core/check.h"
#include "core/rng.h"
#include "core/random_streams.h"

namespace relume {

double LightEvidence::excessError() const {
  if (rays < 2) return INFINITY;
  const double n = static_cast<double>(rays), mean = excess / n;
  const double variance = std::max(0.0, (excessSquares - n * mean * mean) / (n - 1));
  return std::sqrt(variance / n);
}

double LightEvidence::unexplainedShare() const { return observed > 0 ? excess / observed : 0.0; }

void LightEvidence::addObserved(const Color& radiance, const Eigen::Array<bool, 3, 1>& clipped) {
  const double I = luminance(radiance);
  observed += I, observedSquares += I * I, observedColor += radiance;
  for (int c = 0; c < 3; ++c)
    if (!clipped[c]) unclippedColor[c] += radiance[c], ++unclippedRays[c];
  if (clipped.any()) clippedRays.push_back({radiance, clipped});
}

LightEvidence::PixelEmission LightEvidence::pixelEmission(uint64_t minUnclipped, bool raiseClipped) const {
  PixelEmission out;
  if (rays == 0) return out;
  for (int c = 0; c < 3; ++c) {
    const bool measured = raiseClipped && unclippedRays[c] >= std::max<uint64_t>(1, minUnclipped);
    const float unclippedMean = measured ? unclippedColor[c] / static_cast<float>(unclippedRays[c]) : 0.0f;
    double sum = unclippedColor[c];
    for (const ClippedRay& r : clippedRays) {
      if (!r.clipped[c]) continue;
      sum += std::max(r.radiance[c], unclippedMean);
      out.lowerBound |= r.radiance[c] > unclippedMean;
    }
    out.emission[c] = static_cast<float>(sum / static_cast<double>(rays));
  }
  return out;
}

Color LightEvidence::emissionEstimate() const {
  return rays ? Color((excessColor / static_cast<float>(rays)).max(0.0f)) : Color::Zero();
}

Color LightEvidence::albedoEstimate() const {
  Color a = Color::Constant(1.0f);
  for (int c = 0; c < 3; ++c)
    if (reflectorColor[c] > 0) a[c] = std::clamp(observedColor[c] / reflectorColor[c], 0.0f, 1.0f);
  return a;
}

double LightEvidence::constantResidualSquares() const {
  return rays ? std::max(0.0, observedSquares - observed * observed / static_cast<double>(rays)) : 0.0;
}

bool interiorPixel(const Scene& scene, const Camera& camera, const Vec3& p, int object) {
  const auto pixel = camera.project(p);
  if (!pixel || pixel->x() < 1 || pixel->y() < 1 || pixel->x() >= camera.width - 1 || pixel->y() >= camera.height - 1)
    return false;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      if (dx == 0 && dy == 0) continue;
      const auto dir = camera.rayDirection(*pixel + Vec2(dx, dy));
      if (!dir) return false;
      const auto hit = scene.intersect(camera.position, *dir);
      if (!hit || hit->object != object) return false;
    }
  return true;
}

bool besideBrighter(const Scene& scene, const Camera& camera, const Vec3& p, int object, float own,
                    const std::function<std::optional<Color>(const Vec2&)>& frame) {
  const auto pixel = camera.project(p);
  if (!pixel) return false;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      if (dx == 0 && dy == 0) continue;
      const Vec2 q = *pixel + Vec2(dx, dy);
      const auto dir = camera.rayDirection(q);
      if (!dir) continue;
      const auto hit = scene.intersect(camera.position, *dir);
      if (hit && hit->object == object) continue;
      const auto value = frame(q);
      if (value && luminance(*value) > 1.25f * own) return true;
    }
  return false;
}

Appearance albedoOneAppearance(const Appearance& appearance) {
  Appearance white(appearance.objectCount());
  white.model = appearance.model;
  white.roughness = appearance.roughness;
  white.specular = appearance.specular;
  std::fill(white.albedoConstant.begin(), white.albedoConstant.end(), Color::Constant(1.0f));
  std::fill(white.albedoFromTexture.begin(), white.albedoFromTexture.end(), 0);
  return white;
}

std::vector<LightEvidence> gatherLightEvidence(const Scene& scene, const TriangleMesh& mesh,
                                               const Appearance& appearance, const LightSampler& lights,
                                               const std::vector<BatchRay>& rays, const std::vector<int>& objects,
                                               const PathSettings& path, uint64_t seed,
                                               const std::vector<const Camera*>* cameras,
                                               const std::function<std::optional<Color>(size_t, const Vec2&)>*
                                                   framePixel) {
  CHECK(!cameras || cameras->size() == rays.size());
  const size_t n = rays.size();
  // The first vertex of every path evaluated with albedo 1 (sampling stays with the fitted
  // appearance, so the estimate is unbiased whatever the albedo).
  const Appearance white = albedoOneAppearance(appearance);
  const AppearanceScope whiteFirst{&appearance, &white, &appearance, &appearance, &appearance};
  const std::vector<Color> returned = traceRays(scene, lights, whiteFirst, rays, path, [&](size_t j) {
    return hashTuple({seed, streamTag(RandomStream::ReflectorBound), j});
  });

  // Per ray: the own emission seen directly, the model's mirror bound and the perfect mirror's ray.
  std::vector<Color> ownEmission(n, Color::Zero());
  std::vector<float> mirrorBound(n, 0.0f);
  std::vector<uint8_t> valid(n, 0), interior(n, 0), blended(n, 0);
  std::vector<Vec3> point(n), normal(n);
  std::vector<BatchRay> mirrorRays(n);
  tbb::parallel_for(size_t{0}, n, [&](size_t j) {
    const BatchRay& r = rays[j];
    mirrorRays[j].origin = r.origin, mirrorRays[j].dir = r.dir;
    if (!(r.reference.minCoeff() >= 0) || !r.reference.allFinite()) return;
    const auto hit = scene.intersect(r.origin, r.dir);
    if (!hit || hit->object != objects[j]) return;
    valid[j] = 1;
    interior[j] = !cameras || ((*cameras)[j] && interiorPixel(scene, *(*cameras)[j], hit->p, objects[j]));
    if (!interior[j] && framePixel && (*cameras)[j])
      blended[j] = besideBrighter(scene, *(*cameras)[j], hit->p, objects[j], luminance(r.reference),
                                  [&](const Vec2& q) { return (*framePixel)(j, q); });
    ownEmission[j] = emittedRadiance(appearance, *hit, r.dir);
    const Vec3 n0 = hit->ng.dot(r.dir) < 0 ? hit->ng : Vec3(-hit->ng);
    point[j] = hit->p, normal[j] = n0;
    const float cosView = std::min(1.0f, -n0.dot(r.dir));
    const float fresnel = specularFresnel(appearance.model, cosView, 1.0f).value;
    bool first = true;
    forEachMirrorDirection(*hit, r.dir, [&](const Vec3& d) {
      if (first) mirrorRays[j].origin = Scene::offsetOrigin(*hit, d), mirrorRays[j].dir = d, first = false;
      const auto light = scene.intersect(Scene::offsetOrigin(*hit, d), d);
      if (light && light->object != hit->object)
        mirrorBound[j] = std::max(mirrorBound[j], fresnel * luminance(emittedRadiance(appearance, *light, d)));
      return true;
    });
  });
  const std::vector<Color> mirrored =
      traceRays(scene, lights, AppearanceScope::uniform(appearance), mirrorRays, path, [&](size_t j) {
        return hashTuple({seed, streamTag(RandomStream::MirrorPath), j});
      });

  // An object with fewer than kMinInteriorRays interior rays (a lamp never 3x3 pixels wide in any
  // frame) is judged on all its rays rather than on none.
  constexpr uint64_t kMinInteriorRays = 16;
  std::vector<uint64_t> interiorRays(appearance.objectCount(), 0);
  for (size_t j = 0; j < n; ++j) interiorRays[objects[j]] += valid[j] && interior[j];
  std::vector<LightEvidence> out(appearance.objectCount());
  for (size_t f = 0; f < mesh.triangles.size(); ++f)
    if (mesh.faceObject[f] >= 0 && mesh.faceObject[f] < appearance.objectCount())
      out[mesh.faceObject[f]].area += mesh.faceArea[f];
  for (size_t j = 0; j < n; ++j) {
    if (!valid[j] || (!interior[j] && interiorRays[objects[j]] >= kMinInteriorRays) || blended[j]) continue;
    LightEvidence& e = out[objects[j]];
    const Color reflectorColor = (returned[j] - ownEmission[j]).max(0.0f);
    const Color radiance = rays[j].reference / rays[j].gain;  // the frame's pixel as radiance
    const double I = luminance(radiance), B = luminance(reflectorColor) + mirrorBound[j];
    const double P = luminance(mirrored[j]);
    ++e.rays;
    e.addObserved(radiance, rays[j].reference >= rays[j].clip.high);
    e.reflector += B;
    e.reflectorColor += reflectorColor + Color::Constant(mirrorBound[j]);
    e.excess += I - B, e.excessSquares += (I - B) * (I - B);
    e.excessColor += radiance - reflectorColor - Color::Constant(mirrorBound[j]);
    e.mirrorResidualSquares += (I - P) * (I - P);
    if (I > B) {
      e.deficit += I - B;
      e.deficitPoint += (I - B) * point[j].cast<double>();
      e.deficitNormal += (I - B) * normal[j].cast<double>();
    }
  }
  return out;
}

UnderLit underLit(const LightEvidence& e, const LightTestSettings& s) {
  UnderLit u;
  if (e.rays == 0 || !(e.meanExcess() - s.significance * e.excessError() > 0) || e.deficit <= 0) return u;
  u.underLit = true;
  u.missing = e.meanExcess();
  u.centre = (e.deficitPoint / e.deficit).cast<float>();
  if (e.deficitNormal.norm() > 0) u.from = e.deficitNormal.normalized().cast<float>();
  return u;
}

const char* lightVerdictName(LightVerdict v) {
  switch (v) {
    case LightVerdict::Light:
      return "light";
    case LightVerdict::Reflector:
      return "reflector";
    case LightVerdict::OutOfModel:
      return "out_of_model";
    case LightVerdict::Weak:
      return "weak";
    case LightVerdict::NotACandidate:
      return "not_a_candidate";
  }
  return "?";
}

std::vector<LightDecision> decideLights(const std::vector<LightEvidence>& evidence,
                                        const std::vector<uint8_t>& candidate, const LightTestSettings& s,
                                        const std::vector<uint8_t>& emitting) {
  CHECK_EQ(evidence.size(), candidate.size());
  CHECK(emitting.empty() || emitting.size() == evidence.size());
  std::vector<LightDecision> out(evidence.size());
  std::vector<double> power(evidence.size(), 0.0);
  double totalPower = 0;
  // The room's radiance: the median over the candidates that no excess singles out (all of them
  // when every one passes, as when no light is in view).
  const auto floorOnly = [&](const LightEvidence& e) { return s.saturatedFloor && e.seenOnlySaturated(); };
  const auto emits = [&](size_t o) { return !emitting.empty() && emitting[o]; };
  const auto noReflector = [&](const LightEvidence& e) {
    return e.meanExcess() - s.significance * e.excessError() > 0;
  };
  const auto passesExcess = [&](const LightEvidence& e, size_t o) {
    if (floorOnly(e)) return noReflector(e) || emits(o);
    return noReflector(e) && e.unexplainedShare() >= s.minUnexplained;
  };
  std::vector<double> room, all;
  for (size_t o = 0; o < evidence.size(); ++o)
    if (candidate[o] && evidence[o].rays > 0) {
      all.push_back(evidence[o].meanObserved());
      if (!passesExcess(evidence[o], o)) room.push_back(evidence[o].meanObserved());
    }
  std::vector<double>& radiances = room.empty() ? all : room;
  double median = 0;
  if (!radiances.empty()) {
    std::nth_element(radiances.begin(), radiances.begin() + radiances.size() / 2, radiances.end());
    median = radiances[radiances.size() / 2];
  }
  for (size_t o = 0; o < evidence.size(); ++o) {
    const LightEvidence& e = evidence[o];
    LightDecision& d = out[o];
    if (!candidate[o]) {
      d.why = "not a candidate";
      continue;
    }
    if (e.rays == 0) {
      d.verdict = LightVerdict::Reflector;
      d.why = "no ray of its own reached it";
      continue;
    }
    const double x = e.meanExcess(), se = e.excessError(), share = e.unexplainedShare();
    if (!passesExcess(e, o) && floorOnly(e)) {
      d.verdict = LightVerdict::Reflector;
      d.why = fmt::format(
          "seen only saturated, at least {:.3g}; a reflector with albedo <= 1 returns up to {:.3g}: the floor does "
          "not tell them apart, and it does not emit now",
          e.meanObserved(), e.meanReflector());
      continue;
    }
    if (!passesExcess(e, o)) {
      d.verdict = LightVerdict::Reflector;
      d.why = fmt::format(
          "looks {:.3g}; a reflector with albedo <= 1 returns {:.3g} (unexplained {:.0f}% +- {:.0f}%, needs {:.0f}% "
          "and {:.0f} sigma)",
          e.meanObserved(), e.meanReflector(), 100 * share, 100 * se / std::max(1e-30, e.meanObserved()),
          100 * s.minUnexplained, s.significance);
      continue;
    }
    // A floor cannot show a contrast the frames could not record: the lounge's lights, stored at
    // the darkest bracket's clip, sit at 3.8x a bright room's median.
    if (!floorOnly(e) && e.meanObserved() < s.minContrast * median) {
      d.verdict = LightVerdict::Reflector;
      d.why = fmt::format(
          "looks {:.3g}, more than a reflector returns under the lights in view ({:.3g}), but only {:.1f}x the "
          "room's median {:.3g} (needs {:.0f}x): lit by a light the frames do not show?",
          e.meanObserved(), e.meanReflector(), e.meanObserved() / std::max(1e-30, median), median, s.minContrast);
      continue;
    }
    if (e.mirrorResidualSquares < e.constantResidualSquares()) {
      d.verdict = LightVerdict::OutOfModel;
      d.why = fmt::format(
          "looks {:.3g}, more than a reflector of the model returns ({:.3g}), but a mirror explains its pixels "
          "better than an emission does (residual {:.3g} vs {:.3g}): metal, mirror or glass",
          e.meanObserved(), e.meanReflector(), e.mirrorResidualSquares / e.rays, e.constantResidualSquares() / e.rays);
      continue;
    }
    power[o] = e.area * (floorOnly(e) ? e.meanObserved() : x);
    totalPower += power[o];
    d.verdict = LightVerdict::Light;
  }
  for (size_t o = 0; o < evidence.size(); ++o) {
    if (out[o].verdict != LightVerdict::Light) continue;
    const LightEvidence& e = evidence[o];
    out[o].powerShare = totalPower > 0 ? power[o] / totalPower : 0.0;
    const std::string excess =
        floorOnly(e)
            ? fmt::format("seen only saturated, at least {:.3g}; a reflector returns up to {:.3g}{}", e.meanObserved(),
                          e.meanReflector(),
                          noReflector(e) ? "" : ": the floor does not tell them apart, and it emits now")
            : fmt::format("looks {:.3g}; a reflector returns at most {:.3g} (unexplained {:.0f}%, {:.1f} sigma)",
                          e.meanObserved(), e.meanReflector(), 100 * e.unexplainedShare(),
                          e.meanExcess() / std::max(1e-30, e.excessError()));
    if (out[o].powerShare < s.pruneFraction) {
      out[o].verdict = LightVerdict::Weak;
      out[o].why = fmt::format("{}, but {:.2f}% of the power (needs {:.0f}%)", excess, 100 * out[o].powerShare,
                               100 * s.pruneFraction);
    } else {
      out[o].why = fmt::format("{}, {:.1f}% of the power", excess, 100 * out[o].powerShare);
    }
  }
  return out;
}

Json lightDecisionsJson(const std::vector<LightEvidence>& evidence, const std::vector<LightDecision>& decisions,
                        const std::vector<std::string>& names, const LightTestSettings& settings, bool withUnderLit) {
  Json objects = Json::array();
  for (size_t o = 0; o < evidence.size(); ++o) {
    const LightEvidence& e = evidence[o];
    if (decisions[o].verdict == LightVerdict::NotACandidate && e.rays == 0) continue;
    const Color est = e.emissionEstimate();
    objects.push_back({{"id", o},
                       {"name", o < names.size() ? names[o] : std::string()},
                       {"decision", lightVerdictName(decisions[o].verdict)},
                       {"why", decisions[o].why},
                       {"rays", e.rays},
                       {"observed", e.meanObserved()},
                       {"reflector_bound", e.meanReflector()},
                       {"unexplained", e.meanExcess()},
                       {"unexplained_error", std::isfinite(e.excessError()) ? e.excessError() : -1.0},
                       {"unexplained_share", e.unexplainedShare()},
                       {"mirror_residual", e.rays ? e.mirrorResidualSquares / e.rays : 0.0},
                       {"constant_residual", e.rays ? e.constantResidualSquares() / e.rays : 0.0},
                       {"emission_estimate", {est[0], est[1], est[2]}},
                       {"area_m2", e.area},
                       {"power_share", decisions[o].powerShare}});
    const UnderLit u = underLit(e, settings);
    if (withUnderLit && decisions[o].verdict == LightVerdict::Reflector && u.underLit)
      objects.back()["under_lit"] = {{"missing_radiance", u.missing},
                                     {"centre", {u.centre[0], u.centre[1], u.centre[2]}},
                                     {"light_from", {u.from[0], u.from[1], u.from[2]}}};
  }
  return objects;
}

}  // namespace relume
