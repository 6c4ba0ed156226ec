#include "product/prepare_memory.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/error.h"
#include "core/system.h"
#include "sampling/median_sketch.h"

namespace relume {

namespace {
constexpr size_t kSparsestSample = 64;  // the leanest plan samples 64x fewer texels than the default

InitPhasePlan predict(double budgetBytes, const InitPhaseSize& s, int bands, size_t stride) {
  InitPhasePlan p;
  p.budgetBytes = budgetBytes;
  p.rowsPerBand = (s.tileRows + bands - 1) / bands;
  p.bands = (s.tileRows + p.rowsPerBand - 1) / p.rowsPerBand;
  p.gainStride = stride;
  const double texels = static_cast<double>(s.resolution) * s.resolution;
  const double bandTexels = static_cast<double>(p.rowsPerBand) * static_cast<double>(s.tileTexels) * s.resolution;
  const double tileBits = static_cast<double>(s.tileTexels * s.tileTexels) / 8 + 8;  // bits, and the tile list
  p.fixedBytes = s.heldBytes + s.frameCacheBytes + static_cast<double>(s.visibilityEntries) * tileBits;
  const double frames = static_cast<double>(s.keptFrames);
  p.samplePassBytes = 28 * texels + texels / static_cast<double>(stride) * kGainTexelBytes +
                      s.sampleObservationsAtStride1 / static_cast<double>(stride) * kGainObservationBytes +
                      2 * sizeof(double) * frames * frames;  // the normal matrix and its LDLT's copy
  const double statistic = s.median ? MedianSketch::kBytesPerTexel : 24;  // the sketch, or the mean's sums
  p.medianPassBytes = kInitBytesPerTexel * texels + statistic * bandTexels;
  p.agreementPassBytes = (kInitBytesPerTexel + kAgreementBytesPerTexel) * texels;
  return p;
}

bool fits(const InitPhasePlan& p) { return p.peakBytes() <= (1 - InitPhasePlan::kReserve) * p.budgetBytes; }
}  // namespace

double InitPhasePlan::peakBytes() const {
  return fixedBytes + std::max({samplePassBytes, medianPassBytes, agreementPassBytes});
}

Json InitPhasePlan::toJson() const {
  return Json{{"budget_bytes", budgetBytes},         {"median_bands", bands}, {"tile_rows_per_band", rowsPerBand},
              {"gain_sample_stride", gainStride},     {"predicted_peak_bytes", peakBytes()},
              {"fixed_bytes", fixedBytes},            {"sample_pass_bytes", samplePassBytes},
              {"median_pass_bytes", medianPassBytes}, {"agreement_pass_bytes", agreementPassBytes}};
}

InitPhasePlan planInitPhase(double budgetBytes, const InitPhaseSize& size) {
  CHECK(size.tileRows >= 1 && size.defaultGainStride >= 1);
  if (budgetBytes <= 0) return predict(0, size, 1, size.defaultGainStride);
  // The smallest stride (the sample is a result), then the fewest bands (they cost only the frame
  // loop's overhead).
  for (size_t stride = size.defaultGainStride; stride <= size.defaultGainStride * kSparsestSample; stride *= 2)
    for (int bands = 1;; bands = std::min(2 * bands, size.tileRows)) {
      const InitPhasePlan p = predict(budgetBytes, size, bands, stride);
      if (fits(p)) return p;
      if (bands == size.tileRows) break;
    }
  const InitPhasePlan leanest = predict(budgetBytes, size, size.tileRows, size.defaultGainStride * kSparsestSample);
  const double own = std::max({leanest.samplePassBytes, leanest.medianPassBytes, leanest.agreementPassBytes});
  fail("prepare: --memory-budget {} is too small: the init phase needs {} at the least ({} held by the process "
       "(the mesh, its scene, the libraries), {} the frame cache, which --downscale 2 quarters, {} the phase's own "
       "arrays at {}^2, which a smaller first --res quarters per halving)",
       formatBytes(budgetBytes), formatBytes(leanest.peakBytes() / (1 - InitPhasePlan::kReserve)),
       formatBytes(size.heldBytes), formatBytes(size.frameCacheBytes), formatBytes(own), size.resolution);
}

void checkPrepareBudgetUpFront(double budgetBytes, size_t triangles, double frameCacheBytes, size_t texels) {
  if (budgetBytes <= 0) return;
  const double t = static_cast<double>(triangles);
  const double atlas = kPrepareProcessBytes + kAtlasBytesPerTriangle * t;
  const double texelBytes = (kInitBytesPerTexel + kAgreementBytesPerTexel) * static_cast<double>(texels);
  const double init = kPrepareProcessBytes + kSceneBytesPerTriangle * t + frameCacheBytes + texelBytes;
  const double needed = std::max(atlas, init);
  if (needed <= (1 - InitPhasePlan::kReserve) * budgetBytes) return;
  if (atlas >= init)
    fail("prepare: --memory-budget {} is too small: charting the mesh's {} triangles needs {}",
         formatBytes(budgetBytes), triangles, formatBytes(needed / (1 - InitPhasePlan::kReserve)));
  fail("prepare: --memory-budget {} is too small: the init phase needs {} at the least ({} for the mesh's {} "
       "triangles, {} the frame cache, which --downscale 2 quarters; {} the texels of the init resolution, which a "
       "smaller first --res quarters per halving)",
       formatBytes(budgetBytes), formatBytes(needed / (1 - InitPhasePlan::kReserve)),
       formatBytes(kSceneBytesPerTriangle * t), triangles, formatBytes(frameCacheBytes), formatBytes(texelBytes));
}

}  // namespace relume
