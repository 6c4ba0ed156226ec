// Whether the Gauss-Newton albedo (optim/gauss_newton.h) still moves by more than its noise.
//
// Between two checks an entry's least-squares value (GaussNewtonState::unbounded: before the
// step's bounds, which would hide the movement of an entry held at 0 or 1) moves by its noise,
// the new visits' Monte Carlo estimates, and by what is still systematic: the first visits, made
// while the lights, the neighbours and the entry itself were far off, being diluted, and the
// lighting it is fitted under still changing. The noise of two texels two apart is independent
// (a ray's point splats onto the 2x2 texels around it, so they share no ray); the systematic part
// is shared by neighbours, since it follows the lighting and the init, both smooth. So over pairs
// of such texels (same object), with d each one's movement in units of its standard error,
//   mean d^2 = systematic + noise,   mean d_a d_b = systematic,
// and the ratio mean d^2 / (mean d^2 - mean d_a d_b) is the movement over what its noise alone
// gives: about 1 once the albedo only averages its noise, larger while it still moves.
#pragma once
#include <cstdint>
#include <utility>
#include <vector>

#include "optim/gauss_newton.h"

namespace relume {

struct AlbedoMovement {
  double ratio = 0;          // the movement over what its noise alone gives (about 1: settled)
  double movement = 0;       // median of the entries' movement since the last check
  double standardError = 0;  // median of the entries' standard errors now
  size_t pairs = 0;          // pairs compared (both visited before the last check)
};

class AlbedoConvergence {
 public:
  // Follows the pairs of entries (indices into the albedo and the state) `pairs`.
  explicit AlbedoConvergence(std::vector<std::pair<uint32_t, uint32_t>> pairs);

  // The movement since the last call (none at the first: it only takes the values); `bound` as in
  // GaussNewtonState::standardError.
  AlbedoMovement check(const GaussNewtonState& state, float bound);
  size_t size() const { return pairs_.size(); }

  // Each followed entry's value at the last check, pair by pair (NaN: not visited then); a
  // checkpoint holds it, so that a resumed fit compares its next check with the interrupted run's
  // last.
  std::vector<float>& lastValues() { return last_; }

 private:
  std::vector<std::pair<uint32_t, uint32_t>> pairs_;
  std::vector<float> last_;  // 2 per pair; empty before the first check
};

}  // namespace relume
