// Light selection: an emitter object by power (alias table), then a triangle by area, then a
// uniform point. Built from one Appearance and then fixed (sampling is detached from gradients).
#pragma once

#include <memory>

#include "core/alias_table.h"
#include "scene/appearance.h"
#include "scene/scene.h"

namespace relume {

struct LightSample {
  SurfaceHit hit;
  float pdfArea = 0;
};

// A light triangle chosen by LightSampler::pickEmitter, then pickTriangle.
struct LightPick {
  uint32_t emitter = 0, triangle = 0;  // indices into the sampler's emitters and their triangles
};

class LightSampler {
 public:
  LightSampler(const Scene& scene, const Appearance& appearance) : LightSampler(scene, appearance, nullptr) {}
  // The sampler of `appearance` on `previous`'s scene, sharing its triangle tables of the objects
  // that still emit (they depend on the geometry alone; only the choice by power is rebuilt). A fit
  // samples lights by its current emission, so it rebuilds its sampler every iteration; building
  // the tables of a scan's many-triangle candidates anew each time cost ~8% of an iteration.
  LightSampler(const Appearance& appearance, const LightSampler& previous)
      : LightSampler(*previous.scene_, appearance, &previous) {}
  bool empty() const { return objects_.empty(); }
  // A light point in steps, each loading what the next one reads, so that a wavefront of paths
  // (tracePaths) overlaps the chain of cache misses behind a light point on a many-triangle
  // emitter (its alias bin, its triangle, the triangle's face record) with other paths' work:
  // pickEmitter(uObject, uTriangle) chooses the emitter and starts loading its triangle's alias bin,
  // pickTriangle(pick, uTriangle) completes the pick and starts loading the face record, then
  // sampleAt(pick, uPoint). All three need a sampler that is not empty().
  [[gnu::always_inline]] LightPick pickEmitter(float uObject, float uTriangle) const {  // see core/prefetch.h
    const uint32_t emitter = byPower_.sample(uObject);
    const EmitterShape& e = *objects_[emitter].shape;
    const uint32_t bin = e.byArea.bin(uTriangle);
    e.byArea.prefetch(bin);
    prefetchObject(&e.triangles[bin]);  // the bin's own triangle, the likelier pick
    return {emitter, 0};
  }
  LightPick pickTriangle(LightPick pick, float uTriangle) const;
  LightSample sampleAt(const LightPick& pick, const Vec2& uPoint) const;
  // Memory held by the sampler's tables (shared ones counted in full).
  size_t bytes() const;
  // Area density of sampling a point on `object` (0 if it is not an emitter here).
  float pdfArea(int object) const { return object < static_cast<int>(pdfArea_.size()) ? pdfArea_[object] : 0.0f; }

 private:
  // An emitter's triangle with its corners: the point needs no walk from the triangle's vertex
  // indices to the mesh's positions (a second dependent miss).
  struct EmitterTriangle {
    uint32_t prim;
    Vec3 corner[3];
  };
  // An emitting object's triangles, chosen by area: fixed by the geometry, shared between samplers.
  struct EmitterShape {
    std::vector<EmitterTriangle> triangles;
    AliasTable byArea;
    double area = 0;
  };
  struct EmitterObject {
    int object;
    std::shared_ptr<const EmitterShape> shape;
  };
  LightSampler(const Scene& scene, const Appearance& appearance, const LightSampler* previous);
  const Scene* scene_;
  std::vector<EmitterObject> objects_;
  AliasTable byPower_;
  std::vector<float> pdfArea_;
};

}  // namespace relume
