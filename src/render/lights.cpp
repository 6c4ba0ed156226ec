#include "render/lights.h"

#include <cassert>
#include <cmath>

#include "core/error.h"
#include "core/warp.h"

namespace relume {

LightSampler::LightSampler(const Scene& scene, const Appearance& appearance) : scene_(&scene) {
  const TriangleMesh& mesh = scene.mesh();
  std::vector<std::vector<uint32_t>> trisOf(appearance.objectCount());
  for (uint32_t f = 0; f < mesh.triangles.size(); ++f)
    if (mesh.faceObject[f] < appearance.objectCount()) trisOf[mesh.faceObject[f]].push_back(f);
  std::vector<double> power;
  pdfArea_.assign(appearance.objectCount(), 0.0f);
  std::vector<double> objectArea;
  for (int o = 0; o < appearance.objectCount(); ++o) {
    if (trisOf[o].empty() || !appearance.isEmissive(o)) continue;
    EmitterObject e;
    e.object = o;
    std::vector<double> areas;
    areas.reserve(trisOf[o].size());
    e.triangles.reserve(trisOf[o].size());
    double area = 0;
    for (uint32_t f : trisOf[o]) {
      const auto& v = mesh.triangles[f];
      e.triangles.push_back({f, {mesh.positions[v[0]], mesh.positions[v[1]], mesh.positions[v[2]]}});
      areas.push_back(mesh.faceArea[f]), area += mesh.faceArea[f];
    }
    e.byArea = AliasTable(areas);
    const double p = area * kPi * luminance(appearance.meanEmission(o)) + 1e-12;
    if (!std::isfinite(p)) fail("light sampling: object {} ('{}') emits a non-finite power {}", o, appearance.names[o], p);
    power.push_back(p);
    objectArea.push_back(area);
    objects_.push_back(std::move(e));
  }
  if (!objects_.empty()) byPower_ = AliasTable(power);
  for (size_t i = 0; i < objects_.size(); ++i)
    pdfArea_[objects_[i].object] = static_cast<float>(byPower_.pmf(static_cast<uint32_t>(i)) / objectArea[i]);
}

LightPick LightSampler::pickTriangle(LightPick pick, float uTriangle) const {
  assert(pick.emitter < objects_.size());
  const EmitterObject& e = objects_[pick.emitter];
  pick.triangle = e.byArea.sample(uTriangle);
  scene_->prefetchFace(e.triangles[pick.triangle].prim);
  return pick;
}

LightSample LightSampler::sampleAt(const LightPick& pick, const Vec2& uPoint) const {
  const EmitterObject& e = objects_[pick.emitter];
  const EmitterTriangle& t = e.triangles[pick.triangle];
  const Vec2 b = squareToTriangle(uPoint);
  LightSample s;
  s.hit = scene_->hitFromFace(t.prim, b.x(), b.y());
  s.hit.p = barycentricPoint(t.corner[0], t.corner[1], t.corner[2], b.x(), b.y());
  s.pdfArea = pdfArea_[e.object];
  return s;
}

}  // namespace relume
