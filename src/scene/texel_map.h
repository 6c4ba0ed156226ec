// Inverse uv map at one resolution: for every texel centre, the triangle covering it (and so its
// barycentrics and 3D point). Texels a chart only touches, and one ring around every chart, are
// assigned to the nearest triangle (flagged kDilated), so bilinear lookups and gradient scatters
// near chart borders stay inside the chart.
// 4 bytes per texel: barycentrics are recomputed from the triangle's uvs when needed.
#pragma once
#include <cstdint>
#include <vector>

#include "scene/mesh.h"

namespace relume {

inline constexpr int kMaxTextureResolution = 32768;

class TexelMap {
 public:
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  static constexpr uint32_t kDilated = 0x80000000u;  // high bit: centre not on the triangle

  TexelMap() = default;
  TexelMap(const TriangleMesh& mesh, int resolution, int dilationRings = 1);

  int resolution() const { return resolution_; }
  size_t texelCount() const { return entries_.size(); }
  bool valid(size_t texel) const { return entries_[texel] != kEmpty; }
  bool covered(size_t texel) const { return valid(texel) && !(entries_[texel] & kDilated); }
  uint32_t triangle(size_t texel) const { return entries_[texel] & ~kDilated; }
  size_t coveredCount() const { return covered_; }
  size_t bytes() const { return entries_.size() * sizeof(uint32_t); }
  // Barycentrics (b0, b1, b2) of the texel centre in its triangle, clamped onto the triangle for
  // dilated texels.
  Vec3 barycentrics(const TriangleMesh& mesh, size_t texel) const;
  Vec3 point(const TriangleMesh& mesh, size_t texel) const;
  // The surface normal at the texel's point: the mesh's shading normal there (on the side its vertex
  // normals give), or, when the mesh has none or it is unreliable (TriangleMesh::shadingNormal), the
  // triangle's geometric normal; `fellBack` says whether a shading normal existed but was unreliable.
  Vec3 normal(const TriangleMesh& mesh, size_t texel, bool* fellBack = nullptr) const;
  Vec2 texelCentreUv(size_t texel) const {
    return {(static_cast<float>(texel % resolution_) + 0.5f) / resolution_,
            (static_cast<float>(texel / resolution_) + 0.5f) / resolution_};
  }

 private:
  int resolution_ = 0;
  size_t covered_ = 0;
  std::vector<uint32_t> entries_;
};

}  // namespace relume
