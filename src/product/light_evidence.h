// Which objects are light sources, decided from their own pixels. An object is a light source when
// its observed radiance cannot be explained as reflection of the light the rest of the scene sends
// to it, by any albedo in [0, 1] and the BSDF's specular lobe, beyond the noise of both estimates.
//
// For each ray aimed at a surface point of object o (reference I, luminance):
//   B = the radiance the point returns with albedo 1 at that vertex (one path, the current scene:
//       every other surface's albedo and emission as fitted, o's own emission seen directly
//       removed), plus the brightest current light in the mirror direction (or 4 directions 10
//       degrees around it) times the model's Fresnel at specular 1: the most a reflector could
//       return there, since a path's radiance grows with the albedo of its first vertex;
//   x = I - B, the radiance no reflector explains;
//   P = the radiance arriving along the mirror direction (one path): what a perfect mirror returns.
// Over o's rays: x's mean and standard error (the noise of the frames and of B's path together).
// The test (decideLights):
//   light       x_mean - z se > 0 and x_mean >= min_unexplained * I_mean, and the power it
//               implies (area x x_mean) >= prune_fraction of the lights' total;
//   out of model it passes the first test but a perfect mirror explains its pixels better than a
//               constant emission does (sum (I - P)^2 < sum (I - I_mean)^2): metal, mirror or
//               glass showing a light, which relume's BSDF cannot represent;
//   reflector   otherwise (the reflector returns enough);
//   weak        it passes but carries too little of the power to matter;
//   reflector   also when it passes but does not outshine the room (mean I below min_contrast x
//               the median mean I of the candidates that do not pass): when no light in view explains the room,
//               every surface passes, and the brightest wall is no more a light than the rest.
#pragma once
#include <functional>
#include <optional>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"
#include "io/json.h"
#include "render/path_tracer.h"
#include "sampling/batch.h"

namespace relume {

// The mirror direction of `dir` about the geometric normal on the viewer's side, then four
// directions 10 degrees around it (a glossy lobe's width), those above the surface; fn(d) returns
// false to stop.
template <class Fn>
void forEachMirrorDirection(const SurfaceHit& hit, const Vec3& dir, Fn&& fn) {
  const Vec3 n = hit.ng.dot(dir) < 0 ? hit.ng : Vec3(-hit.ng);
  const ShadingFrame frame(dir - 2.0f * dir.dot(n) * n);
  for (int k = 0; k < 5; ++k) {
    const float phi = 0.5f * kPi * k, tilt = k == 0 ? 0.0f : std::sin(10.0f * kPi / 180.0f);
    const Vec3 d = frame.toWorld(Vec3(tilt * std::cos(phi), tilt * std::sin(phi), std::sqrt(1 - tilt * tilt)));
    if (d.dot(n) > 0 && !fn(d)) return;
  }
}

// The share of an object's rays that must clip for it to count as seen only saturated.
inline constexpr double kOnlySaturatedShare = 0.95;
inline bool onlySaturated(uint64_t saturated, uint64_t rays) {
  return rays > 0 && static_cast<double>(saturated) >= kOnlySaturatedShare * static_cast<double>(rays);
}

// Sums over one object's rays; means and errors derived below.
struct LightEvidence {
  uint64_t rays = 0;
  double observed = 0;         // sum of I
  Color observedColor = Color::Zero();
  double reflector = 0;                  // sum of B
  Color reflectorColor = Color::Zero();  // sum of B per channel
  Color excessColor = Color::Zero();     // sum of the colour excess I - B (per channel)
  double excess = 0, excessSquares = 0;  // sum of x, x^2
  double observedSquares = 0;            // sum of I^2
  double mirrorResidualSquares = 0;      // sum of (I - P)^2
  double area = 0;                       // of the object's surface, m^2
  // Where the radiance is more than a reflector returns (x > 0): the sum of x, and of x times the
  // point and its normal (on the viewer's side): where light is missing and which way it faces.
  double deficit = 0;
  Eigen::Vector3d deficitPoint = Eigen::Vector3d::Zero(), deficitNormal = Eigen::Vector3d::Zero();

  // Each channel's unclipped radiance (sum, rays), and every ray with a clipped channel: what the
  // frames show of the emission where they measure it, and where they bound it.
  Color unclippedColor = Color::Zero();
  Eigen::Array<uint64_t, 3, 1> unclippedRays = Eigen::Array<uint64_t, 3, 1>::Zero();
  struct ClippedRay {
    Color radiance;
    Eigen::Array<bool, 3, 1> clipped;
  };
  std::vector<ClippedRay> clippedRays;

  // Adds one ray's pixel, as radiance, with the channels its frame clips (I is its luminance).
  void addObserved(const Color& radiance, const Eigen::Array<bool, 3, 1>& clipped);

  double meanObserved() const { return rays ? observed / rays : 0.0; }
  // Rays whose reference is saturated in some channel: their I is only a lower bound.
  uint64_t saturatedRays() const { return clippedRays.size(); }
  bool seenOnlySaturated() const { return onlySaturated(saturatedRays(), rays); }
  Color meanObservedColor() const { return rays ? Color(observedColor / static_cast<float>(rays)) : Color::Zero(); }
  double meanReflector() const { return rays ? reflector / rays : 0.0; }
  double meanExcess() const { return rays ? excess / rays : 0.0; }
  double excessError() const;       // standard error of the mean excess
  double unexplainedShare() const;  // mean excess / mean observed
  // The emission its own pixels show, per channel: their mean radiance with each clipped value,
  // which shows only that the truth is at least that, raised to the mean of the channel's
  // unclipped values where that is higher (a light seen unclipped in the darker frames of a
  // bracket and clipped in the brighter ones). `lowerBound`: some clipped value stays above that
  // mean, or fewer than `minUnclipped` rays of a channel are unclipped, so the emission is at
  // least this. Without clipped rays it is meanObservedColor(), exact.
  struct PixelEmission {
    Color emission = Color::Zero();
    bool lowerBound = false;
  };
  PixelEmission pixelEmission(uint64_t minUnclipped, bool raiseClipped = true) const;
  // The emission the excess implies (per channel, clamped at 0): the refit's starting point.
  Color emissionEstimate() const;
  // The albedo that makes a reflector return what it shows (per channel, in [0, 1]).
  Color albedoEstimate() const;
  // sum of (I - I_mean)^2: what a constant emission leaves.
  double constantResidualSquares() const;
};

// Whether the pixel of `camera` that sees `p` and its 8 neighbours all show `object` (a pixel at the
// border of the image, or whose neighbours show something else, mixes them into its value).
bool interiorPixel(const Scene& scene, const Camera& camera, const Vec3& p, int object);

// Whether a pixel of another object among the 8 around the pixel that sees `p` is brighter in the
// frame (`frame`: its value at a pixel position) than 1.25x p's own luminance `own`: the pixel
// filter blends it into p's pixel, which then shows more than p (a window's reveal, thin in every
// view, beside the pane). A small lamp's neighbours are darker than it.
bool besideBrighter(const Scene& scene, const Camera& camera, const Vec3& p, int object, float own,
                    const std::function<std::optional<Color>(const Vec2&)>& frame);

// `appearance`'s roughness and specular with albedo 1 everywhere and no emission: evaluated at a
// path's first vertex, what a white surface there would return.
Appearance albedoOneAppearance(const Appearance& appearance);

// Per ray: I, B and P as above (B and P from one path each, seeded from `seed`). Rays whose
// reference is masked, that miss, or that reach another object than `objects[j]` are not counted,
// nor, with `cameras` (ray j's camera), rays whose pixel has a neighbour (of the 8) showing
// another object (or lies on the image border, or has no camera): the pixel filter mixes those
// neighbours into the reference, so an object seen only at its silhouette (a thin string in front
// of a window) would borrow their radiance. An object with fewer than 16 such interior rays is
// judged on all of its rays, except, with `framePixel` (ray j's frame at a pixel position), those
// besideBrighter another object.
std::vector<LightEvidence> gatherLightEvidence(const Scene& scene, const TriangleMesh& mesh,
                                               const Appearance& appearance, const LightSampler& lights,
                                               const std::vector<BatchRay>& rays, const std::vector<int>& objects,
                                               const PathSettings& path, uint64_t seed,
                                               const std::vector<const Camera*>* cameras = nullptr,
                                               const std::function<std::optional<Color>(size_t, const Vec2&)>*
                                                   framePixel = nullptr);

struct LightTestSettings {
  double minUnexplained = 0.5;  // share of its radiance that no reflector returns
  double significance = 3.0;    // z: standard errors the excess must clear
  double pruneFraction = 0.02;  // of the total power the lights imply
  // A light outshines the room: its mean radiance is at least this many times the median of the
  // mean radiances of the candidates that do not pass the excess test (of all of them when every
  // one passes). Below it the excess is taken for light the frames do not show (the object is
  // reported under-lit). 0 = off.
  double minContrast = 4.0;
  // A candidate seen only saturated (kOnlySaturatedShare of its rays clip) shows a floor of its
  // radiance, not its value. A floor can rule a reflector out (mean excess - z se > 0), never a
  // light: when it rules out neither, the object keeps the role it has (emitting or not). Its power
  // is its area times its floor, and the contrast condition does not apply (the frames cannot
  // record a contrast beyond their range). false: the floor is taken as the value (the ablation).
  bool saturatedFloor = true;
};

enum class LightVerdict { Light, Reflector, OutOfModel, Weak, NotACandidate };
// A reflector that is brighter than albedo 1 makes it under the lights in view (x_mean - z se > 0):
// light reaches it that no object in view supplies (a light seen only from behind, outside every
// frame, under a shade). Reported with where that light lands and the direction it comes from.
struct UnderLit {
  bool underLit = false;
  double missing = 0;          // mean radiance no reflector of the lights in view returns
  Vec3 centre = Vec3::Zero();  // of the under-lit points, weighted by what they miss
  Vec3 from = Vec3::Zero();    // unit: the mean normal of those points, so the light lies that way
};
UnderLit underLit(const LightEvidence& e, const LightTestSettings& settings);
const char* lightVerdictName(LightVerdict v);

struct LightDecision {
  LightVerdict verdict = LightVerdict::NotACandidate;
  double powerShare = 0;  // of the total implied by the objects that pass the excess test
  std::string why;        // one line, for the log and the report
};

// One decision per object; objects with candidate[o] == 0 are NotACandidate. `emitting[o]` (empty:
// none) says which objects emit now: an object seen only saturated whose floor does not rule a
// reflector out keeps that role.
std::vector<LightDecision> decideLights(const std::vector<LightEvidence>& evidence,
                                        const std::vector<uint8_t>& candidate, const LightTestSettings& settings,
                                        const std::vector<uint8_t>& emitting = {});

// The evidence and decisions as the report shows them: one entry per object with rays (with
// `under_lit` for the reflectors that are, when `withUnderLit`).
Json lightDecisionsJson(const std::vector<LightEvidence>& evidence, const std::vector<LightDecision>& decisions,
                        const std::vector<std::string>& names, const LightTestSettings& settings, bool withUnderLit);

}  // namespace relume
