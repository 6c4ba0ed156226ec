// Walker/Vose alias table: O(1) sampling of a discrete distribution.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

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
  float pmf(uint32_t i) const { return pmf_[i]; }

 private:
  std::vector<float> prob_, pmf_;
  std::vector<uint32_t> alias_;
};

}  // namespace relume
