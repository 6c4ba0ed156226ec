// The emission of light sources the frames show only saturated (docs/design/light-sources.md,
// "Lights seen only saturated").
//
// A light whose every pixel clips shows only a lower bound on its emission. The surfaces it lights
// are explained as well by brighter lights and darker surfaces as by the truth: with each texel's
// albedo free, a texel's albedo absorbs any scale s of the light it receives directly,
//   a_k(s) = (I_k - s G_k - G_R,k) / (s D_k + R_k),
// I_k what the frames show at texel k, D_k the radiance an albedo-1 texel's diffuse lobe returns
// of the light it receives straight from the clipped lights, R_k the rest (the other lights, and
// the surfaces the frames see, which s does not change since their radiance is observed), G_k and
// G_R,k what its specular lobe returns of each, which the albedo does not scale. What tells s apart is
// that one material has one albedo where the clipped lights reach it directly and where they do
// not (a wall's far corner, the floor under a table, the top of a wall beside a ceiling panel):
// only the true s makes each surface's albedo as uniform as it is. The scale is the s that
// minimises the spread of the log-albedo within each object (each object's Gaussian likelihood with
// its own variance, so a textured rug weighs less than a plain wall), pooled over objects, with a
// jackknife error over objects; with several such lights, each its own where the frames tell them
// apart. The lobes depend on the first vertex's roughness and specular, which no highlight has
// fixed yet when this runs; optionally the lobes are taken apart and each object takes the
// material, among the fit's and a few glossy to matte, under which its albedo is most uniform. The scale is applied only when its
// error is small, and never below what the clipped pixels bound the emission by; then, or in its
// place, the lights are raised until no object's albedo exceeds 1 (albedoCeiling).
#pragma once
#include <array>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "io/json.h"
#include "params/parameters.h"
#include "product/fit_workspace.h"
#include "product/frame_gains.h"
#include "render/path_tracer.h"

namespace relume {

// One texel: what the frames show (I, luminance) and the means over its paths of what an albedo-1
// texel's diffuse lobe returns straight from each clipped light (D_1..D_K) and of everything else
// (R); where `specular` is given, also what its specular lobe returns of each (G_1..G_K, G_R),
// which its albedo does not scale: I = a (s.D + R) + s.G + G_R. With the covariance of those
// means (the paths' noise, which the fit removes from each object's spread: it shrinks relative to
// s D + R as s grows, and left in it pulls s up).
struct ScaleTexel {
  int object = 0;
  uint32_t texel = 0;  // in the texel space the scale was drawn in
  double shown = 0;
  std::vector<double> mean;        // D_1..D_K, R
  std::vector<double> specular;    // G_1..G_K, G_R; empty: no specular lobe
  std::vector<double> covariance;  // of the means, then the specular ones: row-major, (K+1)^2 or (2K+2)^2
};

struct ScaleFit {
  std::vector<double> scale;     // per clipped light
  std::vector<double> logError;  // per light: standard error of log(scale) (its group's)
  bool common = true;            // one scale for all: no two were told apart (or K = 1)
  std::vector<int> groupOf;      // per light, the group whose scale it takes; empty when common
  int objects = 0;               // objects with enough texels
  size_t texels = 0;
  // Each object's own common scale (NaN where it lies on the grid's edge): where they agree.
  std::vector<std::pair<int, double>> perObject;
  // Some light's scale lies further from 1 than its error.
  bool movesLights() const;
  // Some light's scale is known to `maxLogError`.
  bool known(double maxLogError) const;
};

// The fit above. First one scale for all the lights, on a log grid over [1/16, 16] refined by a
// parabola; then, with 2 to 8 lights, the lights in groups, each group's scale by coordinate
// descent and Newton steps around it: one group per light where every one's error is at most
// `maxLogError`; else, from one group per light, a pair whose ratio is within 3 of its errors
// merged (the pair whose log scales are most negatively correlated) until none is (`groups`
// given: those groups, as the luminance fit found them for a channel's). Objects with fewer than
// `minTexels` texels are left out. The errors are infinite with fewer than three objects, when a
// scale lands on the grid's edge or when nothing depends on it.
ScaleFit fitClippedScales(const std::vector<ScaleTexel>& texels, size_t minTexels, double maxLogError,
                          const std::vector<int>& groups = {});

// No albedo exceeds 1. An object's albedo as one value over its texels (what they show over what
// they receive: its texels' albedo weighted by the light each receives, so at most their largest)
// falls as the clipped lights brighten; at the lights' scales s times a common factor t it is at
// most 1 where
//   t >= sum(I - G_R - R) / sum(s.D + s.G),
// a ratio estimate whose standard error comes from its texels' spread about it. The ceiling is the
// largest such bound, less `sigmas` of its error, over the objects with at least `minTexels` texels
// whose bound is finite; 1 when none exceeds 1. A white wall at albedo 0.95 bounds the lights'
// emission from below at 0.95 of the truth, whatever the uniformity of its albedo says.
struct CeilingBound {
  int object = 0;
  double factor = 0, error = 0;  // t_o and its standard error
};
struct AlbedoCeiling {
  double factor = 1;  // the least common factor of the scales that keeps every object's albedo at most 1
  int object = -1;    // the object that sets it (-1: none exceeds 1)
  std::vector<CeilingBound> perObject;
  Json toJson(const Appearance& a) const;
};
AlbedoCeiling albedoCeiling(const std::vector<ScaleTexel>& texels, size_t minTexels, const std::vector<double>& scale,
                            double sigmas);

// The first vertex's roughness and specular each object may take instead of the fit's while its
// clipped lights are scaled: glossy to matte, as interiors have them.
struct FirstVertexMaterial {
  float roughness, specular;
};
inline constexpr std::array<FirstVertexMaterial, 4> kFirstVertexMaterials{
    {{0.15f, 0.9f}, {0.35f, 0.5f}, {0.6f, 0.3f}, {0.9f, 0.15f}}};

// Per object, which of several sets of texels (under[h], each the same texels with the terms
// traced under material h) makes its albedo most uniform at the lights' scales `scale` (the least
// mean log-spread); 0 for objects with fewer than `minTexels` texels in every set.
std::vector<int> chooseFirstVertexMaterials(const std::vector<std::vector<ScaleTexel>>& under, int objectCount,
                                            size_t minTexels, const std::vector<double>& scale);
// The texels of under[h] whose object chose h.
std::vector<ScaleTexel> chosenTexels(const std::vector<std::vector<ScaleTexel>>& under, const std::vector<int>& choice);

struct ClippedLightSettings {
  int texelsPerObject = 1024;  // reflector texels drawn per object
  int framesPerTexel = 4;
  int pathsPerRay = 8;  // of each D and of R (the fit sets clipped_scale_paths)
  // Applied only when the scale is known to ~20%: the init's white point (the brightest surfaces
  // taken for albedo 0.8, when they may be 0.6 or 0.9) is not known better.
  double maxLogError = 0.2;
  // R with each object's albedo at the next vertex scaled to what the frames show of it (the .cpp
  // says why); false: the fit's albedo as it is.
  bool shownRadiance = true;
  // The first vertex's specular lobe apart from its diffuse one (ScaleTexel::specular), and each
  // object's first vertex also under kFirstVertexMaterials, keeping the material its albedo is
  // most uniform under at the lights' shared scale (chooseFirstVertexMaterials), once the scale
  // under the fit's own has settled; false: both lobes as one, the fit's materials.
  bool materialChoice = true;
  // The lights raised, after the uniformity's scale or in its place when that is not known, until
  // no object's albedo exceeds 1 (albedoCeiling, at this many of its errors); false: not.
  bool albedoCeiling = true;
  double ceilingSigmas = 3;
  // Keep the texels of the first fit (under the fit's own materials) in ClippedLightScale::texels,
  // for the lab's diagnosis of the estimator (bench/scale_at_truth.cpp).
  bool keepTexels = false;
};

// What the clipped pixels of a light seen only saturated say.
struct SaturatedFloor {
  double lowerBound = 0;   // the smallest scale of its emission that keeps it at their mean radiance
  double darkestClip = 0;  // the highest radiance (luminance) at which one of them clips: the darkest frame's
};

struct ClippedLightScale {
  std::vector<int> lights;  // the lights seen only saturated
  ScaleFit fit;
  std::vector<SaturatedFloor> floors;  // per light
  // Per light: how much darker than the darkest frame that sees it, in EV (to 0.5), a frame must
  // be to show it unclipped: at its emission after the scale, one EV and two errors above it.
  std::vector<double> darkerFrameEv;
  bool applied = false;
  bool coloured = false;  // each channel scaled by its own fit (else all by the luminance's)
  // Per object: 0 where the fit's own roughness and specular served, h where
  // kFirstVertexMaterials[h - 1] did; empty without the choice.
  std::vector<int> firstVertexMaterial;
  // The choice was to be made but waited: the scale under the fit's own materials still moved.
  bool materialsDeferred = false;
  // At the scales the uniformity gave (1 where it was not known); applied when its factor exceeds 1.
  AlbedoCeiling ceiling;
  // The lights' emission changed by more than its error: by the uniformity's scale, or by the ceiling.
  bool movesLights() const;
  // With ClippedLightSettings::keepTexels: the first fit's texels, per band (red, green, blue,
  // luminance); else empty.
  std::array<std::vector<ScaleTexel>, 4> texels;
  std::string why;        // one line: what was decided and why
  Json toJson(const Appearance& a) const;
};

// The lights among `emitter` seen only saturated: at least 95% of the rays drawn on their own
// texels clip.
std::vector<int> lightsSeenOnlySaturated(const Workspace& w, const TexelSpace& space, const Appearance& a,
                                         const std::vector<uint8_t>& emitter, const FrameGains& gains,
                                         const ClippedLightSettings& settings, uint64_t seed);

// Finds the lights among `emitter` seen only saturated and, when there are any, fits their scale
// in luminance and in each channel, and applies it: their emission x s (per channel when every
// channel's fit is resolved), and each reflector's albedo by its texels' mean a(s) / a(1).
// Each light's scale is at least what its own clipped pixels bound it by.
ClippedLightScale scaleClippedLights(const Workspace& w, const TexelSpace& space, Appearance& a,
                                     const std::vector<uint8_t>& emitter, const std::vector<uint8_t>& outOfModel,
                                     const FrameGains& gains, const PathSettings& path,
                                     const ClippedLightSettings& settings, uint64_t seed);

}  // namespace relume
