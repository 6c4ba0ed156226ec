// Coarse-to-fine transfer of a texel group (values or optimiser state) to a finer resolution:
// bilinear in the texel-centre convention (child centre (x + 0.5) / f maps to parent coordinate
// (x + 0.5) / f - 0.5), chart-masked by normalised convolution: only parent texels that are valid
// and lie on the same object as the child contribute, so gutters and other charts never bleed in.
// A child with no such parent among its four taps takes the nearest one in a 5x5 window.
#pragma once
#include <span>
#include <vector>

#include "scene/texel_map.h"

namespace relume {

std::vector<float> upsampleTexels(std::span<const float> parent, const TexelMap& parentMap, const TexelMap& childMap,
                                  const TriangleMesh& mesh, int channels);

}  // namespace relume
