#include "render/lights.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "core/error.h"
#include "core/warp.h"

namespace relume {

LightSampler::LightSampler(const Scene& scene, const Appearance& appearance, const LightSampler* previous)
    : scene_(&scene) {
  assert(!previous || previous->scene_ == &scene);
  const TriangleMesh& mesh = scene.mesh();
  const int objectCount = appearance.objectCount();
  std::vector<std::shared_ptr<const EmitterShape>> shapeOf(objectCount);
  if (previous)
    for (const EmitterObject& e : previous->objects_)
      if (e.object < objectCount) shapeOf[e.object] = e.shape;
  // Objects that emit now and have no table yet: their triangles, in face order.
  std::vector<uint8_t> emits(objectCount), toBuild(objectCount);
  for (int o = 0; o < objectCount; ++o) emits[o] = appearance.isEmissive(o), toBuild[o] = emits[o] && !shapeOf[o];
  std::vector<std::vector<uint32_t>> trisOf(objectCount);
  if (std::find(toBuild.begin(), toBuild.end(), 1) != toBuild.end())
    for (uint32_t f = 0; f < mesh.triangles.size(); ++f) {
      const int o = mesh.faceObject[f];
      if (o < objectCount && toBuild[o]) trisOf[o].push_back(f);
    }
  std::vector<double> power;
  pdfArea_.assign(objectCount, 0.0f);
  for (int o = 0; o < objectCount; ++o) {
    if (!emits[o]) continue;
    if (!shapeOf[o]) {
      if (trisOf[o].empty()) continue;
      auto shape = std::make_shared<EmitterShape>();
      std::vector<double> areas;
      areas.reserve(trisOf[o].size());
      shape->triangles.reserve(trisOf[o].size());
      for (uint32_t f : trisOf[o]) {
        const auto& v = mesh.triangles[f];
        shape->triangles.push_back({f, {mesh.positions[v[0]], mesh.positions[v[1]], mesh.positions[v[2]]}});
        areas.push_back(mesh.faceArea[f]), shape->area += mesh.faceArea[f];
      }
      shape->byArea = AliasTable(areas);
      shapeOf[o] = std::move(shape);
    }
    const double p = shapeOf[o]->area * kPi * luminance(appearance.meanEmission(o)) + 1e-12;
    if (!std::isfinite(p)) fail("light sampling: object {} ('{}') emits a non-finite power {}", o, appearance.names[o], p);
    power.push_back(p);
    objects_.push_back({o, shapeOf[o]});
  }
  if (!objects_.empty()) byPower_ = AliasTable(power);
  for (size_t i = 0; i < objects_.size(); ++i)
    pdfArea_[objects_[i].object] = static_cast<float>(byPower_.pmf(static_cast<uint32_t>(i)) / objects_[i].shape->area);
}

size_t LightSampler::bytes() const {
  size_t n = byPower_.bytes() + pdfArea_.size() * sizeof(float) + objects_.size() * sizeof(EmitterObject);
  for (const EmitterObject& e : objects_) n += e.shape->triangles.size() * sizeof(EmitterTriangle) + e.shape->byArea.bytes();
  return n;
}

LightPick LightSampler::pickTriangle(LightPick pick, float uTriangle) const {
  assert(pick.emitter < objects_.size());
  const EmitterShape& e = *objects_[pick.emitter].shape;
  pick.triangle = e.byArea.sample(uTriangle);
  scene_->prefetchFace(e.triangles[pick.triangle].prim);
  return pick;
}

LightSample LightSampler::sampleAt(const LightPick& pick, const Vec2& uPoint) const {
  const EmitterObject& e = objects_[pick.emitter];
  const EmitterTriangle& t = e.shape->triangles[pick.triangle];
  const Vec2 b = squareToTriangle(uPoint);
  LightSample s;
  s.hit = scene_->hitFromFace(t.prim, b.x(), b.y());
  s.hit.p = barycentricPoint(t.corner[0], t.corner[1], t.corner[2], b.x(), b.y());
  s.pdfArea = pdfArea_[e.object];
  return s;
}

}  // namespace relume
