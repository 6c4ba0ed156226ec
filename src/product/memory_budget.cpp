#include "product/memory_budget.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/check.h"
#include "core/error.h"
#include "core/system.h"

namespace relume {

TexelBytes texelBytes(const FitConfig& c, double sampleableFraction) {
  constexpr double kRgb = 3 * sizeof(float);  // one float per channel
  const bool newton = c.albedoStep == AlbedoStep::GaussNewton;
  const bool spread = newton && c.albedoStandardError;
  TexelBytes b;
  b.albedo = kRgb;
  // The map's triangle index, the updatable flag, and the sampleable list (its capacity: up to
  // twice what it holds).
  b.texelMap = sizeof(uint32_t) + 1 + 2 * sizeof(uint32_t) * sampleableFraction;
  // Gauss-Newton: numerator, curvature and visit counts (+ the spread: residual and weight
  // squares); Adam: two moments and step counts.
  b.stepState = 2 * kRgb + 3 * sizeof(uint16_t) + (spread ? 2 * kRgb : 0);
  // The albedo's gradient (+ its curvature), and a byte per texel of each marking it splatted.
  b.gradients = (newton ? 2 : 1) * (kRgb + 1);
  b.average = c.polyakFraction > 0 ? kRgb : 0;
  // The settled albedo's standard errors; with the smoothing, its arrays (eligible and used
  // flags, points, the values and errors it returns, the adjacent differences it takes the
  // guide's noise from, up to two per texel with their vectors' slack) and the guide (prepare's
  // median radiance, upsampled, and its log luminance).
  if (spread) {
    b.settling = kRgb;
    if (c.albedoSmoothing != AlbedoSmoothing::None) {
      b.settling += 2 + 3 * sizeof(float) + 2 * kRgb + 4 * sizeof(float);
      if (c.albedoSmoothing == AlbedoSmoothing::GuideEdges) b.settling += kRgb + sizeof(float);
    }
  }
  // The result (fit_result.cpp), written after the last stage: the standard errors, and the
  // images it writes one after the other with the encoders' copies: the albedo, its errors, the
  // confidence channels and picture, and one conversion to 8 bits or half floats in flight.
  const double result = (spread ? kRgb : 0) + 5 * kRgb;
  b.settling = std::max(b.settling, result);
  return b;
}

Json MemoryPlan::toJson() const {
  Json j = {{"budget_bytes", budgetBytes}, {"resolution", resolution}};
  for (const MemoryEstimate& e : estimates)
    j["predicted"].push_back(
        {{"resolution", e.resolution}, {"peak_bytes", e.peakBytes()}, {"fixed_bytes", e.fixedBytes}});
  return j;
}

MemoryPlan planMemory(double budgetBytes, const std::vector<int>& resolutions, double fixedBytes,
                      double frameCacheBytes, const TexelBytes& perTexel) {
  CHECK(!resolutions.empty() && std::is_sorted(resolutions.begin(), resolutions.end()));
  MemoryPlan plan;
  plan.budgetBytes = budgetBytes;
  for (int r : resolutions) {
    MemoryEstimate e{r, fixedBytes, perTexel.peak() * static_cast<double>(r) * r};
    plan.estimates.push_back(e);
    if (e.peakBytes() <= (1 - MemoryPlan::kReserve) * budgetBytes) plan.resolution = r;
  }
  const MemoryEstimate& coarsest = plan.estimates.front();
  if (plan.resolution == 0)
    fail("memory budget {} is too small for this fit: it is predicted to need {} at its coarsest albedo resolution "
         "{}^2, so a budget of {} with the {:.0f}% reserve ({} of it whatever the resolution, {} of that the frame "
         "cache: its file mapping becomes resident as the frames are read; prepare --downscale 2 quarters it)",
         formatBytes(budgetBytes), formatBytes(coarsest.peakBytes()), coarsest.resolution,
         formatBytes(coarsest.peakBytes() / (1 - MemoryPlan::kReserve)), 100 * MemoryPlan::kReserve,
         formatBytes(coarsest.fixedBytes), formatBytes(frameCacheBytes));
  return plan;
}

}  // namespace relume
