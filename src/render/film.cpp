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
// Counts the path's rays and keeps its first vertex (the AOVs are read there).
struct PixelObserver : NullPathObserver {
  uint64_t rays = 0;
  std::optional<SurfaceHit> first;
  void traced(const Vec3&, const Vec3&, float, bool) { ++rays; }
  void vertex(int depth, const SurfaceHit& hit, const ShadingFrame&, const Vec3&, const Color&) {
    if (depth == 0) first = hit;
  }
};
}  // namespace

CameraSample cameraSample(const Camera& camera, int x, int y, int s, uint64_t seed) {
  CameraSample cs{Pcg32(hashTuple({static_cast<uint64_t>(y) * camera.width + x, static_cast<uint64_t>(s), seed, 0x7265})), {}};
  const Vec2 pixel(x + cs.rng.next1D(), y + cs.rng.next1D());
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
    const int x0 = r.cols().begin(), y0 = r.rows().begin(), tileW = r.cols().end() - x0;
    const size_t pixels = static_cast<size_t>(tileW) * (r.rows().end() - y0), spp = options.spp;
    std::vector<Color> sum(pixels, Color::Zero());
    std::vector<std::optional<SurfaceHit>> first(pixels);  // sample 0's first vertex
    std::array<PixelObserver, kPathGroup> obs;
    // Path j of the tile: pixel j / spp (row-major in the tile), sample j % spp.
    tracePathsGrouped(
        scene, lights, scope, options.path, 0, pixels * spp, obs,
        [&](size_t j, PathState& s, Pcg32& rng, PixelObserver& o) {
          const int x = x0 + static_cast<int>(j / spp % tileW), y = y0 + static_cast<int>(j / spp / tileW);
          CameraSample cs = cameraSample(camera, x, y, static_cast<int>(j % spp), options.seed);
          if (!cs.dir) return false;
          s.origin = camera.position, s.dir = *cs.dir, rng = cs.rng;
          o.first.reset();
          return true;
        },
        [&](size_t j, const Color& L, PixelObserver& o) {
          if (isFinite(L)) sum[j / spp] += L;
          if (j % spp == 0) first[j / spp] = o.first;
        });
    for (size_t i = 0; i < pixels; ++i) {
      const int x = x0 + static_cast<int>(i % tileW), y = y0 + static_cast<int>(i / tileW);
      result.color.set(x, y, sum[i] / static_cast<float>(options.spp));
      if (!first[i]) continue;
      const SurfaceHit& hit = *first[i];
      for (size_t a = 0; a < options.aovs.size(); ++a) {
        Color v = Color::Zero();
        switch (options.aovs[a]) {
          case Aov::Albedo: v = appearance.albedoAt(hit.object, hit.uv); break;
          case Aov::Normal: v = hit.ns.array(); break;
          case Aov::Depth: v = Color::Constant((hit.p - camera.position).dot(camera.rotation.col(2))); break;
          case Aov::Object: v = Color::Constant(static_cast<float>(hit.object)); break;
        }
        result.aovs[a].set(x, y, v);
      }
    }
    if (x0 == 0) progress.advance(r.rows().size());
    for (const PixelObserver& o : obs) rayCount.local() += o.rays;
  });
  result.stats.seconds = timer.seconds();
  result.stats.paths = static_cast<uint64_t>(W) * H * options.spp;
  result.stats.rays = rayCount.combine(std::plus<>());
  return result;
}

}  // namespace relume
