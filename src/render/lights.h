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

class LightSampler {
 public:
  LightSampler(const Scene& scene, const Appearance& appearance);
  bool empty() const { return objects_.empty(); }
  std::optional<LightSample> sample(float uObject, float uTriangle, const Vec2& uPoint) const;
  // Area density of sampling a point on `object` (0 if it is not an emitter here).
  float pdfArea(int object) const { return object < static_cast<int>(pdfArea_.size()) ? pdfArea_[object] : 0.0f; }

 private:
  struct EmitterObject {
    int object;
    std::vector<uint32_t> triangles;
    AliasTable byArea;
  };
  const Scene* scene_;
  std::vector<EmitterObject> objects_;
  AliasTable byPower_;
  std::vector<float> pdfArea_;
};

}  // namespace relume
