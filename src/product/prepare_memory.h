// A prepare within a memory budget (`relume prepare --memory-budget 2G`): the init phase, where
// prepare peaks, is planned to fit, or the run is refused, naming the figure it would need.
//
// Model of the init phase's peak (docs/design/texture-space.md, "Memory"): what the process holds when
// it plans (the mesh, Embree's BVH, the texel map, the libraries: its resident set after the heap
// is trimmed), plus the whole frame-cache mapping (file-backed: its pages count towards the
// resident set once read), the occlusion bits and tile lists of the visibility entries, plus the
// largest of its three passes:
//  - the frame gains' sample: room for `frames of its tile` observations per sampled texel, each
//    with its weight in the solve, and the solve's dense normal matrix over the kept frames and its
//    factorisation's copy;
//  - the median: the texels' points and normals, coverage and the two output images, and the
//    median sketch of one band of tile rows (a band's texels are a contiguous range);
//  - the agreement: the same arrays and the agreement's own.
// Two levers, neither changing anything but memory and the gain sample: the median runs band by
// band (every texel's median is the same in any band), and the gains sample every n-th texel.
#pragma once
#include <cstddef>

#include "io/json.h"

namespace relume {

struct InitPhaseSize {
  double heldBytes = 0;        // resident when the phase is planned
  double frameCacheBytes = 0;  // frames.bin, mapped whole
  int resolution = 0;          // the init resolution
  int tileRows = 1;            // tiles per side of the init resolution
  bool median = true;          // the init statistic is the median (else the mean: 24 bytes per texel)
  size_t visibilityEntries = 0;
  size_t tileTexels = 32;  // per side
  // The gain sample's observations at stride 1: per texel, the frames its tile lists (a bound:
  // every one of them seeing every texel of the tile).
  double sampleObservationsAtStride1 = 0;
  size_t defaultGainStride = 1;  // prepare's own stride (kConsistencyTexels sampled texels)
  size_t keptFrames = 0;         // the gains' unknowns
};

struct InitPhasePlan {
  // Of the budget, kept in reserve for what the model leaves out (allocator slack, OpenImageIO's
  // buffers while it writes the images).
  static constexpr double kReserve = 0.05;
  double budgetBytes = 0;  // 0: no budget (one band, the default stride)
  int rowsPerBand = 1;     // the median's tile rows, this many at a time
  int bands = 1;           // how many bands that makes
  size_t gainStride = 1;   // one texel in gainStride sampled for the frame gains
  double fixedBytes = 0, samplePassBytes = 0, medianPassBytes = 0, agreementPassBytes = 0;
  double peakBytes() const;
  Json toJson() const;
};

// Per texel, what the init phase holds beside the sketch or sample: points and normals (24), coverage (4),
// the init albedo and coverage images (24); in the agreement pass also its sums and image (36).
constexpr double kInitBytesPerTexel = 52, kAgreementBytesPerTexel = 36;
// A sampled observation (its frame index and colour, reserved for every frame of its tile), its
// weight in the solve; and a sampled texel's two arrays' headers.
constexpr double kGainObservationBytes = 24, kGainTexelBytes = 48;

// Without a budget (budgetBytes 0): one band and the default stride, the prediction filled in.
// With one: the smallest stride (no smaller than the default; the sample is a result), then the
// fewest bands, whose peak is within the budget less its reserve. Throws relume::Error naming the
// figure the leanest plan (one tile row per band, a 64x sparser sample) needs when none fits.
InitPhasePlan planInitPhase(double budgetBytes, const InitPhaseSize& size);

// Before any phase: whether the leanest plan can fit, from what is known without work (the mesh's
// triangles, the frames' sizes, the init resolution). The larger of two phases, both measured:
// the atlas (the process, and kAtlasBytesPerTriangle while it charts) and the init phase at its
// leanest (the process, the scene per triangle, the frame cache and the texels' arrays). Throws
// relume::Error naming the figure when not.
constexpr double kPrepareProcessBytes = 135.0 * (1 << 20), kAtlasBytesPerTriangle = 300,
                 kSceneBytesPerTriangle = 210;
void checkPrepareBudgetUpFront(double budgetBytes, size_t triangles, double frameCacheBytes, size_t texels);

}  // namespace relume
