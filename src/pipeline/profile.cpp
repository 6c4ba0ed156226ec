#include "pipeline/profile.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "core/system.h"
#include "render/film.h"

namespace relume {
namespace {

struct RecordedRay {
  Vec3 origin, dir;
  float tmax;
  bool shadow;
};

struct RayRecorder : NullPathObserver {
  std::vector<RecordedRay>* out;
  void traced(const Vec3& o, const Vec3& d, float tmax, bool shadow) { out->push_back({o, d, tmax, shadow}); }
};

}  // namespace

RenderProfile profileRender(const SceneDescription& desc, const Camera& camera, int spp, int maxDepth) {
  Scene scene(desc.mesh);
  LightSampler lights(scene, desc.appearance);
  RenderOptions ro;
  ro.spp = spp;
  ro.path.maxDepth = maxDepth;
  renderImage(scene, desc.appearance, lights, camera, ro);  // warm-up (page faults, BVH in cache)
  const RenderResult r = renderImage(scene, desc.appearance, lights, camera, ro);

  // Record the same paths' rays (same seeds), then time Embree alone on them.
  tbb::enumerable_thread_specific<std::vector<RecordedRay>> recorded;
  const AppearanceScope scope = AppearanceScope::uniform(desc.appearance);
  tbb::parallel_for(0, camera.height, [&](int y) {
    RayRecorder rec;
    rec.out = &recorded.local();
    for (int x = 0; x < camera.width; ++x)
      for (int s = 0; s < spp; ++s) {
        Pcg32 rng(hashTuple({static_cast<uint64_t>(y) * camera.width + x, static_cast<uint64_t>(s), ro.seed, 0x7265}));
        const Vec2 pixel(x + rng.next1D(), y + rng.next1D());
        if (const auto dir = camera.rayDirection(pixel)) tracePath(scene, lights, scope, ro.path, camera.position, *dir, rng, rec);
      }
  });
  std::vector<RecordedRay> rays;
  for (auto& v : recorded) rays.insert(rays.end(), v.begin(), v.end());
  RenderProfile p;
  p.width = camera.width, p.height = camera.height, p.spp = spp, p.maxDepth = maxDepth, p.threads = threadCount();
  p.renderSeconds = r.stats.seconds;
  p.paths = r.stats.paths;
  for (const RecordedRay& ray : rays) (ray.shadow ? p.shadowRays : p.closestRays)++;
  Timer t;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 4096), [&](const tbb::blocked_range<size_t>& range) {
    size_t hits = 0;
    for (size_t i = range.begin(); i < range.end(); ++i) {
      const RecordedRay& ray = rays[i];
      if (ray.shadow) hits += scene.occluded(ray.origin, ray.dir, ray.tmax);
      else hits += std::isfinite(scene.hitDistance(ray.origin, ray.dir, ray.tmax));
    }
    volatile size_t sink = hits;  // keep the traversal from being optimised away
    (void)sink;
  });
  p.traceOnlySeconds = t.seconds();
  return p;
}

}  // namespace relume
