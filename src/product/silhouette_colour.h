// The colour of a light the frames show only saturated, measured at its silhouette
// (docs/design/light-sources.md, "Lights seen only saturated").
//
// A light seen only saturated is white at the encoding's maximum in every pixel that shows it
// whole, so its own pixels say nothing of its colour, and the surfaces it lights confuse its colour
// with their albedo. A pixel at its outline covers it in part: through the pixel filter it mixes a
// share f of the emission E with what lies behind, I = f E + (1 - f) B. Where f E stays below the
// maximum in every channel (a few percent of a bright lamp), the pixel measures E's colour. B is
// taken from the pixels just beyond the filter's reach of the light (the per-channel median of
// those near the pixel), then, in radiance (the frame's gain divided out),
//   x = I - B,  f = lum(x) / (lum(E) - lum(B)),  E' = x / f + B,  colour = E' / lum(E'),
// with lum(E) the current emission's luminance, at least the frame's clip level (the light clips
// there). Where E outshines B the colour hardly depends on lum(E). Over the light's pixels the
// colour is the weighted mean of the log colour (weights lum(x)^2 over the background's spread^2
// and the 8-bit step^2), after dropping pixels beyond 4 robust deviations of the weighted median,
// normalised to luminance 1; its error a jackknife over 8 x 8 tiles and over frames. Pixels are labelled by the mesh at their centres, so a pose off by a pixel
// moves which ones count, not what they measure.
#pragma once
#include <cstdint>
#include <vector>

#include "core/math.h"
#include "io/json.h"
#include "product/fit_workspace.h"
#include "product/frame_gains.h"

namespace relume {

struct SilhouetteColourSettings {
  int maxFrames = 32;  // per light, spread evenly over the kept frames it may be in
  // A frame whose region around the light is larger than this many stored pixels is skipped (a
  // light that fills the view has its outline in the next frames).
  size_t maxPixelsPerFrame = size_t{1} << 20;
  // A pixel counts when the light adds at least this share of the frame's clip level to it in
  // luminance (well above the steps of an 8-bit encoding) and at least `minOverBackground` times
  // what lies behind it (so an error in B moves the colour little).
  double minExcess = 0.05;
  double minOverBackground = 0.25;
  // ... and at least this many times the background's noise (its spread, and the 8-bit step).
  double minSignificance = 3;
  double maxShareOfClip = 0.8;  // a pixel counts where every channel is at most this share of the clip level
  int minPixels = 8;
  double maxLogError = 0.1;  // per channel: the colour is used when known to this
};

struct SilhouetteColour {
  int light = -1;
  Color colour = Color::Ones();  // luminance 1
  Color logError = Color::Constant(INFINITY);
  size_t pixels = 0;
  int frames = 0;
  bool measured = false;  // enough pixels for a colour (else `colour` is white, meaning nothing)
  bool known = false;     // measured, and to maxLogError
  Json toJson() const;
};

// The colours of `lights` (objects) at their silhouettes in the kept frames; `emission` per
// object, `emitter` per object (other lights' pixels are no background).
std::vector<SilhouetteColour> measureSilhouetteColours(const Workspace& w, const FrameGains& gains,
                                                       const std::vector<int>& lights,
                                                       const std::vector<Color>& emission,
                                                       const std::vector<uint8_t>& emitter,
                                                       const SilhouetteColourSettings& settings = {});

// The weighted median of `values` (weights > 0); NaN when empty.
double weightedMedian(std::vector<std::pair<double, double>> valueWeight);

}  // namespace relume
