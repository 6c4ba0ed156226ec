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

// A light triangle chosen by LightSampler::pickEmitter (the emitter), then pickTriangle (the triangle).
struct LightPick {
  uint32_t emitter = 0;   // index into the sampler's emitters
  uint32_t triangle = 0;  // into the emitter's triangles; set by pickTriangle
};

class LightSampler {
 public:
  // With `previous` (a sampler of the same scene), its triangle tables are taken over, those of the
  // objects dark now included (they depend on the geometry alone), and only the choice by power is
  // built anew: a fit samples lights by its current emission, so it rebuilds its sampler every
  // iteration, and rebuilding the tables of a scan's 1M triangles of candidates each time cost ~8%
  // of an emission-stage iteration. Sampling is the same as without.
  LightSampler(const Scene& scene, const Appearance& appearance, const LightSampler* previous = nullptr);
  bool empty() const { return emitters_.empty(); }
  // A light point in steps, each loading what the next one reads, so that a wavefront of paths
  // (tracePaths) overlaps the chain of cache misses behind a light point on a many-triangle
  // emitter (its alias bin, its triangle, the triangle's face record) with other paths' work:
  // pickEmitter(uObject, uTriangle) chooses the emitter and starts loading the bin of its by-area
  // table that uTriangle falls in, and that bin's triangle; pickTriangle(pick, uTriangle) chooses
  // the triangle and starts loading its face record; sampleAt(pick, uPoint) forms the point. All
  // three need a sampler that is not empty().
  [[gnu::always_inline]] LightPick pickEmitter(float uObject, float uTriangle) const {  // see core/prefetch.h
    const uint32_t emitter = byPower_.sample(uObject);
    const EmitterShape& e = *emitters_[emitter].shape;
    const uint32_t bin = e.byArea.bin(uTriangle);
    e.byArea.prefetch(bin);
    prefetchObject(&e.triangles[bin]);  // the bin's own triangle, the likelier pick
    return {emitter};
  }
  LightPick pickTriangle(LightPick pick, float uTriangle) const;
  LightSample sampleAt(const LightPick& pick, const Vec2& uPoint) const;
  // Area density of sampling a point on `object` (0 if it is not an emitter here).
  float pdfArea(int object) const { return object < static_cast<int>(pdfArea_.size()) ? pdfArea_[object] : 0.0f; }
  // Memory held by the sampler's tables (shared ones counted in full), and how many of its
  // objects' tables it built rather than took over.
  size_t bytes() const;
  size_t builtTables() const { return builtTables_; }

 private:
  // An emitter's triangle with its corners: the point needs no walk from the triangle's vertex
  // indices to the mesh's positions (a second dependent miss).
  struct EmitterTriangle {
    uint32_t prim;
    Vec3 corner[3];
  };
  // An object's triangles, chosen by area: fixed by the geometry, shared between samplers.
  struct EmitterShape {
    std::vector<EmitterTriangle> triangles;
    AliasTable byArea;
    double area = 0;
  };
  struct Emitter {
    int object;
    const EmitterShape* shape;  // owned by shapes_
  };
  const Scene* scene_;
  std::vector<std::shared_ptr<const EmitterShape>> shapes_;  // per object; null until it first emits
  std::vector<Emitter> emitters_;
  AliasTable byPower_;
  std::vector<float> pdfArea_;
  size_t builtTables_ = 0;
};

}  // namespace relume
