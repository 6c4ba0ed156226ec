// Light selection: an emitter object by power (alias table), then a triangle by area, then a
// uniform point. Built from one Appearance and then fixed (sampling is detached from gradients).
#pragma once
#include <optional>

#include "core/alias_table.h"
#include "scene/appearance.h"
#include "scene/scene.h"

namespace relume {

struct LightSample {
  SurfaceHit hit;
  float pdfArea = 0;
};

// A light triangle chosen by LightSampler::pick.
struct LightPick {
  uint32_t emitter = 0, triangle = 0;  // indices into the sampler's emitters and their triangles
};

class LightSampler {
 public:
  LightSampler(const Scene& scene, const Appearance& appearance);
  bool empty() const { return objects_.empty(); }
  // One light point: sampleAt(pick(uObject, uTriangle), uPoint); nothing when there is no emitter.
  std::optional<LightSample> sample(float uObject, float uTriangle, const Vec2& uPoint) const;
  // The same in steps, each loading what the next one reads, so that a wavefront of paths
  // (tracePaths) overlaps the chain of cache misses behind a light point on a many-triangle
  // emitter (its alias bin, its triangle, the triangle's face record) with other paths' work.
  // Call only when !empty(). always_inline, as Texture::prefetch: else GCC deletes the call.
  [[gnu::always_inline]] void prefetchPick(float uObject, float uTriangle) const {
    const EmitterObject& e = objects_[byPower_.sample(uObject)];
    const uint32_t bin = e.byArea.bin(uTriangle);
    e.byArea.prefetch(bin);
    __builtin_prefetch(&e.triangles[bin]);  // the bin's own triangle, the likelier pick
    __builtin_prefetch(reinterpret_cast<const char*>(&e.triangles[bin] + 1) - 1);
  }
  // Chooses the triangle and starts loading its face record.
  LightPick pick(float uObject, float uTriangle) const;
  LightSample sampleAt(const LightPick& pick, const Vec2& uPoint) const;
  // Area density of sampling a point on `object` (0 if it is not an emitter here).
  float pdfArea(int object) const { return object < static_cast<int>(pdfArea_.size()) ? pdfArea_[object] : 0.0f; }

 private:
  // An emitter's triangle with its corners: the point needs no walk from the triangle's vertex
  // indices to the mesh's positions (a second dependent miss).
  struct EmitterTriangle {
    uint32_t prim;
    Vec3 corner[3];
  };
  struct EmitterObject {
    int object;
    std::vector<EmitterTriangle> triangles;
    AliasTable byArea;
  };
  const Scene* scene_;
  std::vector<EmitterObject> objects_;
  AliasTable byPower_;
  std::vector<float> pdfArea_;
};

}  // namespace relume
