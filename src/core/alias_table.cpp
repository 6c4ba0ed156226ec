#include "core/alias_table.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace relume {

AliasTable::AliasTable(const std::vector<double>& weights) {
  double sum = 0.0;
  for (size_t i = 0; i < weights.size(); ++i) {
    if (!(weights[i] >= 0.0 && std::isfinite(weights[i])))
      fail("alias table: weight {} is {} (must be finite and >= 0)", i, weights[i]);
    sum += weights[i];
  }
  if (!(sum > 0.0 && std::isfinite(sum)))
    fail("alias table: the {} weights sum to {} (must be finite and > 0)", weights.size(), sum);
  const size_t n = weights.size();
  prob_.resize(n);
  pmf_.resize(n);
  alias_.resize(n);
  std::vector<double> scaled(n);
  std::vector<uint32_t> small, large;
  for (size_t i = 0; i < n; ++i) {
    pmf_[i] = static_cast<float>(weights[i] / sum);
    scaled[i] = weights[i] / sum * static_cast<double>(n);
    (scaled[i] < 1.0 ? small : large).push_back(static_cast<uint32_t>(i));
  }
  while (!small.empty() && !large.empty()) {
    const uint32_t s = small.back(), l = large.back();
    small.pop_back();
    prob_[s] = static_cast<float>(scaled[s]);
    alias_[s] = l;
    scaled[l] -= 1.0 - scaled[s];
    if (scaled[l] < 1.0) {
      large.pop_back();
      small.push_back(l);
    }
  }
  for (uint32_t i : large) prob_[i] = 1.0f, alias_[i] = i;
  for (uint32_t i : small) prob_[i] = 1.0f, alias_[i] = i;  // round-off leftovers
}

uint32_t AliasTable::sample(float u) const {
  const float x = u * static_cast<float>(prob_.size());
  const uint32_t i = binAt(x);
  const float frac = x - static_cast<float>(i);
  return frac < prob_[i] ? i : alias_[i];
}

}  // namespace relume
