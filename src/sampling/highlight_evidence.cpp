#include "sampling/highlight_evidence.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/error.h"

namespace relume {

HighlightEvidence::HighlightEvidence(int objects)
    : texels_(objects, 0), sum_(objects, 0.0), sumSquares_(objects, 0.0) {}

void HighlightEvidence::addBatch(std::span<const uint32_t> slot, std::span<const int> object,
                                 std::span<const float> luminance, std::span<const int8_t> sawLight) {
  const size_t n = slot.size();
  if (object.size() != n || luminance.size() != n || sawLight.size() != n)
    fail("highlight evidence: batch arrays differ in size");
  for (size_t begin = 0, end = 0; begin < n; begin = end) {
    double sum[2] = {0, 0};
    int count[2] = {0, 0};
    for (end = begin; end < n && slot[end] == slot[begin]; ++end)
      if (sawLight[end] == 0 || sawLight[end] == 1) sum[sawLight[end]] += luminance[end], ++count[sawLight[end]];
    if (!count[0] || !count[1] || !(sum[0] > 0) || !std::isfinite(sum[1])) continue;
    const double c = (sum[1] / count[1]) / (sum[0] / count[0]) - 1;
    const int o = object[begin];
    if (o < 0 || o >= static_cast<int>(texels_.size())) continue;
    ++texels_[o], sum_[o] += c, sumSquares_[o] += c * c;
  }
}

double HighlightEvidence::contrast(int o) const { return texels_[o] ? sum_[o] / texels_[o] : 0.0; }

double HighlightEvidence::standardError(int o) const {
  const double n = static_cast<double>(texels_[o]);
  if (n < 2) return 0.0;
  const double mean = contrast(o);
  return std::sqrt(std::max(0.0, (sumSquares_[o] - n * mean * mean) / (n - 1)) / n);
}

bool HighlightEvidence::observed(int o, int minTexels, double minContrast) const {
  return texels_[o] >= static_cast<uint64_t>(std::max(minTexels, 1)) &&
         contrast(o) - 2 * standardError(o) >= minContrast;
}

RoughnessFromAbsence roughnessFromAbsence(double observed, double observedError, std::span<const float> grid,
                                          std::span<const double> rendered, std::span<const double> renderedError) {
  CHECK(!grid.empty() && grid.back() == 1.0f && rendered.size() == grid.size() && renderedError.size() == grid.size());
  CHECK(std::is_sorted(grid.begin(), grid.end()));
  // A highlight only adds light: a texel darker with a light reflected (occlusion the mesh lacks,
  // noise) says nothing about the lobe, and counted as it is it would rule out what the frames
  // cannot.
  const double shown = std::max(observed, 0.0);
  const auto allowed = [&](size_t k) {
    return rendered[k] - shown <= 2 * std::sqrt(observedError * observedError + renderedError[k] * renderedError[k]);
  };
  RoughnessFromAbsence r;
  if (!allowed(grid.size() - 1)) {
    r.roughestRuledOut = true;
    return r;
  }
  size_t lowest = grid.size() - 1;
  while (lowest > 0 && allowed(lowest - 1)) --lowest;
  r.atLeast = grid[lowest];
  r.chosen = 0.5f * (r.atLeast + 1.0f);
  if (lowest == 0) return r;
  size_t smoothestRuledOut = 0;
  while (allowed(smoothestRuledOut)) ++smoothestRuledOut;
  if (smoothestRuledOut > 0) r.sharpBelow = 0.5f * (grid[smoothestRuledOut - 1] + grid[smoothestRuledOut]);
  return r;
}

}  // namespace relume
