// Per-frame gains from the frames alone. A diffuse surface sends the same radiance towards every
// frame, so where two frames see one texel the ratio of their pixels is the ratio of their gains:
// log I_fx = log g_f + log L_x. The least-squares solution over all texels seen by several frames
// is exact in one solve (the texel unknowns eliminated leave a frames x frames system), whatever
// the scene's lighting and materials, and robust weights (Huber, in log units) keep specular
// highlights and misregistered edges from pulling it. The gauge: the gains' geometric mean is 1.
#pragma once
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "core/math.h"

namespace relume {

struct GainObservation {
  uint32_t frame;
  Color value;  // linear, unclipped and positive in every channel
};

struct ConsistencyGains {
  std::vector<Color> gain;          // per frame (1 for frames without evidence)
  std::vector<uint32_t> texels;     // per frame: texels that tied it to another frame
  std::vector<double> residualRms;  // per channel: of log I - log g - log L over the weighted observations
};

// `observations[x]`: texel x's observations (texels with fewer than 2 are skipped). Frames outside
// `kept` must not appear.
// Over MPI ranks a collective: every rank passes the same observations and gets the same gains.
ConsistencyGains solveConsistencyGains(const std::vector<std::vector<GainObservation>>& observations, size_t frameCount,
                                       std::span<const uint32_t> kept);

// prepare's frame_gains.json: per kept frame its gain and texel count, and the residual's RMS.
// Written atomically.
void writeConsistencyGains(const std::filesystem::path& file, const ConsistencyGains& gains,
                           std::span<const uint32_t> kept);
// The gains of `frameCount` frames (1 for frames the file does not list). Throws relume::Error
// naming the file and field on a frame out of range or a gain that is not positive and finite.
std::vector<Color> readConsistencyGains(const std::filesystem::path& file, size_t frameCount);

}  // namespace relume
