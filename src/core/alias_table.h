// Walker/Vose alias table: O(1) sampling of a discrete distribution.
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/prefetch.h"

namespace relume {

class AliasTable {
 public:
  AliasTable() = default;
  // Weights must be finite and >= 0 with a finite positive sum; otherwise throws relume::Error.
  explicit AliasTable(const std::vector<double>& weights);
  bool empty() const { return prob_.empty(); }
  size_t size() const { return prob_.size(); }
  // u in [0,1): returns an index; pmf(i) its probability.
  uint32_t sample(float u) const;
  // The bin sample(u) reads (the index it returns, or that bin's alias), and a prefetch of it
  // (always_inline: see core/prefetch.h). Both need a table that is not empty.
  uint32_t bin(float u) const { return binAt(u * static_cast<float>(prob_.size())); }
  [[gnu::always_inline]] void prefetch(uint32_t i) const {
    prefetchObject(&prob_[i]);
    prefetchObject(&alias_[i]);
  }
  float pmf(uint32_t i) const { return pmf_[i]; }
  size_t bytes() const { return size() * (2 * sizeof(float) + sizeof(uint32_t)); }

 private:
  // x = u * size, formed once by each caller (so that no compiler fuses it differently in one).
  uint32_t binAt(float x) const { return std::min(static_cast<uint32_t>(x), static_cast<uint32_t>(prob_.size() - 1)); }
  std::vector<float> prob_, pmf_;
  std::vector<uint32_t> alias_;
};

}  // namespace relume
