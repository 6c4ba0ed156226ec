#include "render/film.h"

#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <sstream>

#include "core/error.h"
#include "core/system.h"

namespace relume {

std::vector<Aov> parseAovs(const std::string& list) {
  std::vector<Aov> out;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    if (name.empty()) continue;
    if (name == "albedo") out.push_back(Aov::Albedo);
    else if (name == "normal") out.push_back(Aov::Normal);
    else if (name == "depth") out.push_back(Aov::Depth);
    else if (name == "object") out.push_back(Aov::Object);
    else fail("unknown AOV '{}' (albedo, normal, depth, object)", name);
  }
  return out;
}

const char* aovName(Aov aov) {
  switch (aov) {
    case Aov::Albedo: return "albedo";
    case Aov::Normal: return "normal";
    case Aov::Depth: return "depth";
    case Aov::Object: return "object";
  }
  return "";
}

namespace {
struct RayCounter : NullPathObserver {
  uint64_t rays = 0;
  void traced(const Vec3&, const Vec3&, float, bool) { ++rays; }
};
}  // namespace

CameraSample cameraSample(const Camera& camera, int x, int y, int s, uint64_t seed) {
  CameraSample cs{Pcg32(hashTuple({static_cast<uint64_t>(y) * camera.width + x, static_cast<uint64_t>(s), seed, 0x7265})), {}};
  const Vec2 pixel(x + camera.filter.sample(cs.rng.next1D()), y + camera.filter.sample(cs.rng.next1D()));
  cs.dir = camera.rayDirection(pixel);
  return cs;
}

RenderResult renderImage(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                         const Camera& camera, const RenderOptions& options) {
  RenderResult result;
  const int W = camera.width, H = camera.height;
  result.color = Image(W, H);
  for (size_t i = 0; i < options.aovs.size(); ++i) result.aovs.emplace_back(W, H);
  const AppearanceScope scope = AppearanceScope::uniform(appearance);
  tbb::combinable<uint64_t> rayCount([] { return uint64_t{0}; });
  Timer timer;
  Progress progress("render", static_cast<size_t>(H));
  tbb::parallel_for(tbb::blocked_range2d<int>(0, H, 16, 0, W, 16), [&](const tbb::blocked_range2d<int>& r) {
    RayCounter counter;
    for (int y = r.rows().begin(); y < r.rows().end(); ++y) {
      for (int x = r.cols().begin(); x < r.cols().end(); ++x) {
        Color sum = Color::Zero();
        SurfaceHit first{};
        bool anyHit = false;
        for (int s = 0; s < options.spp; ++s) {
          CameraSample cs = cameraSample(camera, x, y, s, options.seed);
          if (!cs.dir) continue;
          SurfaceHit hit;
          hit.t = -1.0f;
          const Color L = tracePath(scene, lights, scope, options.path, camera.position, *cs.dir, cs.rng, counter, s == 0 ? &hit : nullptr);
          if (isFinite(L)) sum += L;
          if (s == 0 && hit.t >= 0.0f) first = hit, anyHit = true;
        }
        result.color.set(x, y, sum / static_cast<float>(options.spp));
        if (!anyHit) continue;
        for (size_t a = 0; a < options.aovs.size(); ++a) {
          Color v = Color::Zero();
          switch (options.aovs[a]) {
            case Aov::Albedo: v = appearance.albedoAt(first.object, first.uv); break;
            case Aov::Normal: v = first.ns.array(); break;
            case Aov::Depth: v = Color::Constant((first.p - camera.position).dot(camera.rotation.col(2))); break;
            case Aov::Object: v = Color::Constant(static_cast<float>(first.object)); break;
          }
          result.aovs[a].set(x, y, v);
        }
      }
      if (r.cols().begin() == 0) progress.advance(1);
    }
    rayCount.local() += counter.rays;
  });
  result.stats.seconds = timer.seconds();
  result.stats.paths = static_cast<uint64_t>(W) * H * options.spp;
  result.stats.rays = rayCount.combine(std::plus<>());
  return result;
}

}  // namespace relume
