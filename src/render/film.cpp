#include "render/film.h"

#include <tbb/blocked_range2d.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include <sstream>

#include "core/error.h"
#include "core/system.h"
#include "core/random_streams.h"

namespace relume {

std::vector<Aov> parseAovs(const std::string& list) {
  std::vector<Aov> out;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    if (name.empty()) continue;
    if (name == "albedo")
      out.push_back(Aov::Albedo);
    else if (name == "normal")
      out.push_back(Aov::Normal);
    else if (name == "depth")
      out.push_back(Aov::Depth);
    else if (name == "object")
      out.push_back(Aov::Object);
    else
      fail("unknown AOV '{}' (albedo, normal, depth, object)", name);
  }
  return out;
}

const char* aovName(Aov aov) {
  switch (aov) {
    case Aov::Albedo:
      return "albedo";
    case Aov::Normal:
      return "normal";
    case Aov::Depth:
      return "depth";
    case Aov::Object:
      return "object";
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
  CameraSample cs{Pcg32(hashTuple({static_cast<uint64_t>(y) * camera.width + x, static_cast<uint64_t>(s), seed,
                                   streamTag(RandomStream::FilmPixel)})),
                  {}};
  const Vec2 u = cs.rng.next2D();
  const Vec2 pixel(x + camera.filter.sample(u.x()), y + camera.filter.sample(u.y()));
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
  tbb::combinable<uint64_t> rayCount([] { return uint64_t{0}; }), nonFiniteCount([] { return uint64_t{0}; });
  Timer timer;
  Progress progress("render", static_cast<size_t>(H));
  tbb::parallel_for(tbb::blocked_range2d<int>(0, H, 16, 0, W, 16), [&](const tbb::blocked_range2d<int>& r) {
    RayCounter counter;
    const int tileW = r.cols().size(), spp = options.spp;
    const size_t pixels = static_cast<size_t>(r.rows().size()) * tileW;
    // The tile's paths, pixel by pixel and sample by sample, traced a wave at a time; each pixel
    // sums its samples in order, in double (spp radiances near float's largest value would overflow
    // a float sum), and keeps its first sample's hit.
    std::vector<Eigen::Array3d> sum(pixels, Eigen::Array3d::Zero());
    uint64_t nonFinite = 0;
    std::vector<SurfaceHit> first(pixels);
    for (SurfaceHit& h : first) h.t = -1.0f;
    std::vector<PathSlot> wave;
    const size_t samples = pixels * spp;
    forEachWave(0, samples, kWavefrontWidth, [&](size_t b, size_t e) {
      wave.clear();
      for (size_t k = b; k < e; ++k) {
        const size_t pixel = k / spp;
        const int s = static_cast<int>(k % spp);
        const int x = r.cols().begin() + static_cast<int>(pixel % tileW),
                  y = r.rows().begin() + static_cast<int>(pixel / tileW);
        const CameraSample cs = cameraSample(camera, x, y, s, options.seed);
        PathSlot& p = wave.emplace_back(camera.position, cs.dir.value_or(Vec3::UnitZ()), cs.rng,
                                        s == 0 ? &first[pixel] : nullptr);
        p.alive = cs.dir.has_value();
      }
      tracePaths(scene, lights, scope, options.path, std::span<PathSlot>(wave),
                 [&](size_t) -> RayCounter& { return counter; });
      for (size_t k = b; k < e; ++k)
        if (const Color& L = wave[k - b].L; isFinite(L))
          sum[k / spp] += L.cast<double>();
        else
          ++nonFinite;
    });
    for (int y = r.rows().begin(); y < r.rows().end(); ++y) {
      for (int x = r.cols().begin(); x < r.cols().end(); ++x) {
        const size_t pixel = static_cast<size_t>(y - r.rows().begin()) * tileW + (x - r.cols().begin());
        result.color.set(x, y, Color((sum[pixel] / spp).cast<float>()));
        const SurfaceHit& hit = first[pixel];
        if (hit.t < 0.0f) continue;
        for (size_t a = 0; a < options.aovs.size(); ++a) {
          Color v = Color::Zero();
          switch (options.aovs[a]) {
            case Aov::Albedo:
              v = appearance.albedoAt(hit.object, hit.uv);
              break;
            case Aov::Normal:
              v = hit.ns.array();
              break;
            case Aov::Depth:
              v = Color::Constant((hit.p - camera.position).dot(camera.rotation.col(2)));
              break;
            case Aov::Object:
              v = Color::Constant(static_cast<float>(hit.object));
              break;
          }
          result.aovs[a].set(x, y, v);
        }
      }
    }
    if (r.cols().begin() == 0) progress.advance(r.rows().size());
    rayCount.local() += counter.rays;
    nonFiniteCount.local() += nonFinite;
  });
  scene.throwIfEmbreeFailed();
  result.stats.seconds = timer.seconds();
  result.stats.paths = static_cast<uint64_t>(W) * H * options.spp;
  result.stats.rays = rayCount.combine(std::plus<>());
  result.stats.nonFinitePaths = nonFiniteCount.combine(std::plus<>());
  return result;
}

}  // namespace relume
