// Damped diagonal Gauss-Newton step, for unknowns the loss is nearly linear in: each pixel is
// linear in the albedo at its first vertex (I = a X + C), so the residual divided by that
// sensitivity is how far the albedo is off. Per entry, with g the gradient and h the curvature
// the adjoint pass accumulates, x h - g = sum (I - C) X' no longer depends on x; the step keeps
// running averages of it and of h over the entry's visits and sets x to their ratio: a running
// weighted least-squares fit of the entry to every ray it has seen (the primal's noise in a X
// cancels between the two, unlike in an average of per-visit Newton targets x - g / h).
// The first visit is the full Newton step x - g / h; visit n weighs 1/n (a plain average) until
// 1/n falls to `damping`, then an exponential average over ~1/damping visits (the lights and
// the neighbours still move). Entries with no gradient this iteration are left alone, as in
// masked Adam. Adam's step is about lr whatever the residual, so a texel 0.3 too dark needs
// ~0.3 / lr visits at full signal and many more at the 1-spp noise level.
// With `trackSpread`, the state also estimates each entry's standard error: x = sum_k c_k n_k /
// sum_k c_k h_k (c_k the visits' weights, summing to 1; n_k = x h_k - g_k), so x - x* is
// sum_k c_k (n_k - x* h_k) / H and its variance sum_k c_k^2 Var(n_k - x* h_k) / H^2. The state
// keeps sum_k c_k^2 and a running average, with the same weights, of the squared residual of each
// visit about the value it was taken at, n_k - x h_k = -g_k (once x has settled near x*, its
// variance; before, larger, so the error errs high).
#pragma once
#include <cstdint>
#include <span>
#include <vector>

namespace relume {

struct GaussNewtonSettings {
  float damping = 0.1f;   // weight of a visit once 1/n is below it
  float maxStep = 0.25f;  // bound on |step| per iteration, in value units (guards rare huge residuals)
};

class GaussNewtonState {
 public:
  GaussNewtonState() = default;
  explicit GaussNewtonState(size_t entries, bool trackSpread = false)
      : numerator(entries, 0.0f),
        curvature(entries, 0.0f),
        steps(entries, 0),
        residualSquare(trackSpread ? entries : 0, -1.0f),
        weightSquare(trackSpread ? entries : 0, 0.0f) {}
  size_t size() const { return curvature.size(); }
  bool tracksSpread() const { return !weightSquare.empty(); }
  // Entry i's standard error, at most `bound` (the width of the entry's domain: no estimate inside
  // it is further off, while the formula divides by a curvature that a texel seen with next to no
  // sensitivity leaves near 0); negative when unknown (no spread tracked, or no visit yet).
  float standardError(size_t i, float bound) const;
  // Entry i's least-squares value without the bounds the steps project onto (numerator / curvature):
  // above hi where the frames ask for more than the domain allows; NaN where nothing was seen.
  float unbounded(size_t i) const;
  // One step on x with gradient g and curvature sample h, then projection onto [lo, hi].
  // Returns the entries updated. (The fit steps through stepTexels; this is its reference.)
  size_t step(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo, float hi,
              const GaussNewtonSettings& s);
  // The same step on the entries of `texels` alone (3 consecutive entries each, RGB), each texel
  // listed at most once: when every other entry has no gradient this is step() at the cost of
  // the batch rather than the texture.
  size_t stepTexels(std::span<float> x, std::span<const float> g, std::span<const float> h, float lo, float hi,
                    const GaussNewtonSettings& s, std::span<const uint32_t> texels);

  std::vector<float> numerator;  // running average of x h - g
  std::vector<float> curvature;  // running average of h
  std::vector<uint16_t> steps;   // visits, saturating
  std::vector<float> residualSquare;  // with trackSpread: running average of g^2; < 0: no visit yet
  std::vector<float> weightSquare;    // with trackSpread: sum of the squared weights of the visits in the fit

 private:
  bool stepEntry(size_t i, std::span<float> x, std::span<const float> g, std::span<const float> h, float lo, float hi,
                 const GaussNewtonSettings& s);
};

}  // namespace relume
