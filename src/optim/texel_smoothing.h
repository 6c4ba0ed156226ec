// Edge-keeping smoothing of a per-texel estimate by its standard errors: the fitted albedo is a
// least-squares fit of each texel to its own rays (optim/gauss_newton.h), so neighbouring texels of
// a uniform wall carry independent noise of a few percent that a texture shows as grain. Each
// eligible texel becomes a weighted mean over the eligible texels of its object within `radius`
// texels on the surface (3D distance, so charts that touch in the atlas do not mix), weighted by
//   - a Gaussian of the distance (sigma radius / 2),
//   - the neighbour's inverse variance,
//   - how well it agrees with the texel: exp(-z^2 / (2 significance^2)), z^2 the squared
//     difference over the sum of both variances, mean over channels; a step the standard errors
//     resolve (an edge) keeps its neighbours out.
// With a guide (the median init: the frames' radiance, with their edges), a neighbour is also
// weighed by how well its guide agrees with the texel's, by the same significance, against the
// guide's own noise (per object, from the median difference of adjacent texels' log luminance):
// edges the frames show stay even where the estimate's noise would hide them, and the guide's
// noise never enters the result. (Smoothing the ratio to the guide instead keeps its edges too but
// carries its noise into the result: measured worse, docs/notes/2026-11-26-albedo-grain.md.)
// The result's standard error is that of the weighted mean (neighbours' errors independent; any
// bias the neighbours share is not in it).
#pragma once
#include <cstdint>
#include <span>
#include <vector>

#include "scene/texel_map.h"

namespace relume {

struct TexelSmoothingSettings {
  int radius = 2;               // window half-width in texels
  float significance = 2.0f;    // standard errors at which a difference keeps a neighbour out (soft)
  float minGuide = 1e-3f;       // a guide channel below this leaves the texel as it is
};

struct SmoothedTexels {
  std::vector<float> values;         // RGB per texel
  std::vector<float> standardError;  // RGB per texel; negative where unknown (as given)
  size_t smoothed = 0;               // texels that had at least one neighbour
};

// `values` and `standardError` are RGB per texel of `map`; `eligible` per texel (updatable texels
// with a known standard error, of objects whose albedo is fitted); `guide` RGB per texel or empty.
// Texels that are not eligible keep their values and errors.
SmoothedTexels smoothTexels(const TexelMap& map, const TriangleMesh& mesh, std::span<const float> values,
                            std::span<const float> standardError, std::span<const uint8_t> eligible,
                            std::span<const float> guide, const TexelSmoothingSettings& s);

}  // namespace relume
