#include "render/lights.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "core/error.h"
#include "core/warp.h"

namespace relume {

LightSampler::LightSampler(const Scene& scene, const Appearance& appearance, const LightSampler* previous)
    : scene_(&scene) {
  CHECK(!previous || previous->scene_ == &scene);
  const TriangleMesh& mesh = scene.mesh();
  const int objectCount = appearance.objectCount();
  shapes_.resize(objectCount);
  if (previous)
    for (size_t o = 0; o < std::min(shapes_.size(), previous->shapes_.size()); ++o) shapes_[o] = previous->shapes_[o];
  // Objects that emit now and have no table yet: their triangles, in face order.
  std::vector<Color> mean(objectCount);
  std::vector<uint8_t> emits(objectCount), toBuild(objectCount);
  for (int o = 0; o < objectCount; ++o) {
    mean[o] = appearance.meanEmission(o);  // an emission texture is averaged once
    emits[o] = mean[o].maxCoeff() > 0.0f;  // Appearance::isEmissive
    toBuild[o] = emits[o] && !shapes_[o];
  }
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
    if (toBuild[o]) {  // an object without faces gets an empty table, not a search every time
      auto shape = std::make_shared<EmitterShape>();
      std::vector<double> areas;
      areas.reserve(trisOf[o].size());
      shape->triangles.reserve(trisOf[o].size());
      for (uint32_t f : trisOf[o]) {
        const auto& v = mesh.triangles[f];
        shape->triangles.push_back({f, {mesh.positions[v[0]], mesh.positions[v[1]], mesh.positions[v[2]]}});
        areas.push_back(mesh.faceArea[f]), shape->area += mesh.faceArea[f];
      }
      if (!areas.empty()) shape->byArea = AliasTable(areas);
      shapes_[o] = std::move(shape);
      ++builtTables_;
    }
    if (shapes_[o]->triangles.empty()) continue;
    const double p = shapes_[o]->area * kPi * luminance(mean[o]) + 1e-12;
    if (!std::isfinite(p))
      fail("light sampling: object {} ('{}') emits a non-finite power {}", o, appearance.names[o], p);
    power.push_back(p);
    emitters_.push_back({o, shapes_[o].get()});
  }
  if (!emitters_.empty()) byPower_ = AliasTable(power);
  for (size_t i = 0; i < emitters_.size(); ++i)
    pdfArea_[emitters_[i].object] =
        static_cast<float>(byPower_.pmf(static_cast<uint32_t>(i)) / emitters_[i].shape->area);
}

size_t LightSampler::bytes() const {
  size_t n = byPower_.bytes() + pdfArea_.size() * sizeof(float) + emitters_.size() * sizeof(Emitter) +
             shapes_.size() * sizeof(shapes_[0]);
  for (const auto& shape : shapes_)
    if (shape) n += shape->triangles.size() * sizeof(EmitterTriangle) + shape->byArea.bytes();
  return n;
}

LightPick LightSampler::pickTriangle(LightPick pick, float uTriangle) const {
  DCHECK(pick.emitter < emitters_.size());
  const EmitterShape& e = *emitters_[pick.emitter].shape;
  pick.triangle = e.byArea.sample(uTriangle);
  scene_->prefetchFace(e.triangles[pick.triangle].prim);
  return pick;
}

LightSample LightSampler::sampleAt(const LightPick& pick, const Vec2& uPoint) const {
  const Emitter& e = emitters_[pick.emitter];
  const EmitterTriangle& t = e.shape->triangles[pick.triangle];
  const Vec2 b = squareToTriangle(uPoint);
  LightSample s;
  s.hit = scene_->hitFromFace(t.prim, b.x(), b.y());
  s.hit.p = barycentricPoint(t.corner[0], t.corner[1], t.corner[2], b.x(), b.y());
  s.pdfArea = pdfArea_[e.object];
  return s;
}

}  // namespace relume
