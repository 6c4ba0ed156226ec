#include "sampling/face_appearance.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "sampling/visibility.h"

namespace relume {
namespace {

struct Observation {
  Color logValue;
  bool clipped;
};

// Median and standard error (from the median absolute deviation) of channel c of `obs`.
std::pair<float, float> robustMean(std::vector<Observation>& obs, int c, std::vector<float>& scratch,
                                   float minSpread) {
  scratch.clear();
  for (const Observation& o : obs) scratch.push_back(o.logValue[c]);
  const size_t n = scratch.size(), mid = n / 2;
  std::nth_element(scratch.begin(), scratch.begin() + mid, scratch.end());
  const float median = scratch[mid];
  for (float& v : scratch) v = std::abs(v - median);
  std::nth_element(scratch.begin(), scratch.begin() + mid, scratch.end());
  const float spread = std::max(1.4826f * scratch[mid], minSpread);
  return {median, spread / std::sqrt(static_cast<float>(n))};
}

// Whether the pixels around `pixel` show the surface of face f (component `component`, plane
// through p with normal n).
bool pixelsAroundShowFace(const Scene& scene, const std::vector<uint32_t>& component, uint32_t f, const Camera& cam,
                          const Vec2& pixel, const Vec3& p, const Vec3& n, float planeTolerance) {
  const float tolerance = planeTolerance * (p - cam.position).norm();
  for (const Vec2& offset : {Vec2(-1.5f, -1.5f), Vec2(1.5f, -1.5f), Vec2(-1.5f, 1.5f), Vec2(1.5f, 1.5f)}) {
    const auto dir = cam.rayDirection(pixel + offset);
    if (!dir) return false;
    const RayHit hit = scene.traverse(cam.position, *dir);
    if (!hit.found() || component[hit.prim] != component[f]) return false;
    if (std::abs(n.dot(cam.position + hit.t * *dir - p)) > tolerance) return false;
  }
  return true;
}

}  // namespace

std::vector<FaceAppearance> observeFaces(const Scene& scene, const std::vector<Frame>& frames,
                                         const FrameStore& store, const std::vector<size_t>& use,
                                         const FaceAppearanceOptions& o) {
  const TriangleMesh& mesh = scene.mesh();
  std::vector<size_t> chosen;
  const size_t count = std::min(o.maxFrames, use.size());
  for (size_t i = 0; i < count; ++i) chosen.push_back(use[i * use.size() / count]);
  const std::vector<uint32_t> component = connectedComponents(mesh);
  std::vector<FaceAppearance> out(mesh.triangles.size());
  struct Scratch {
    std::vector<Observation> all, unclipped;
    std::vector<float> values;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(size_t{0}, mesh.triangles.size(), [&](size_t f) {
    Scratch& s = scratch.local();
    s.all.clear(), s.unclipped.clear();
    const Eigen::Vector3i& t = mesh.triangles[f];
    const Vec3 centre = (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3.0f;
    const Vec3 n = mesh.faceNormal(f);
    const Vec3 points[4] = {centre, 0.5f * (centre + mesh.positions[t[0]]), 0.5f * (centre + mesh.positions[t[1]]),
                            0.5f * (centre + mesh.positions[t[2]])};
    for (size_t k : chosen)
      for (const Vec3& p : points) {
        const auto px = observe(scene, frames[k].camera, p, n);
        if (!px || !pixelsAroundShowFace(scene, component, static_cast<uint32_t>(f), frames[k].camera, *px, p, n,
                                         o.planeTolerance))
          continue;
        const auto c = store.bilinear(k, *px);
        if (!c) continue;
        const bool clipped = (*c >= store.stats(k).clipHigh).any();
        s.all.push_back({c->max(o.radianceFloor).log(), clipped});
        if (!clipped) s.unclipped.push_back(s.all.back());
      }
    if (s.all.empty()) return;
    FaceAppearance& a = out[f];
    a.observed = true;
    a.clippedFraction = static_cast<float>(s.all.size() - s.unclipped.size()) / s.all.size();
    if (s.unclipped.empty()) {  // every observation a floor: the tightest one
      a.logRadiance = Color::Constant(-INFINITY);
      for (const Observation& x : s.all) a.logRadiance = a.logRadiance.max(x.logValue);
      a.logError = Color::Constant(o.minLogSpread);
      return;
    }
    for (int c = 0; c < 3; ++c)
      std::tie(a.logRadiance[c], a.logError[c]) = robustMean(s.unclipped, c, s.values, o.minLogSpread);
  });
  return out;
}

}  // namespace relume
