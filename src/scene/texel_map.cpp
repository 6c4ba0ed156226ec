#include "scene/texel_map.h"

#include <tbb/parallel_for.h>

#include <atomic>

#include "core/error.h"

namespace relume {
namespace {

// Barycentrics of p in the uv triangle (a, b, c); the centroid when the triangle has no uv area
// (never NaN, whatever the uvs).
Vec3 barycentricOf(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const double d =
      (double(b.x()) - a.x()) * (double(c.y()) - a.y()) - (double(b.y()) - a.y()) * (double(c.x()) - a.x());
  if (!(std::abs(d) > 0.0) || !std::isfinite(d)) return Vec3::Constant(1.0f / 3.0f);
  const double b1 =
      ((double(p.x()) - a.x()) * (double(c.y()) - a.y()) - (double(p.y()) - a.y()) * (double(c.x()) - a.x())) / d;
  const double b2 =
      ((double(b.x()) - a.x()) * (double(p.y()) - a.y()) - (double(b.y()) - a.y()) * (double(p.x()) - a.x())) / d;
  return Vec3d(1.0 - b1 - b2, b1, b2).cast<float>();
}

}  // namespace

TexelMap::TexelMap(const TriangleMesh& mesh, int resolution, int rings) : resolution_(resolution) {
  if (!mesh.hasUv()) fail("texel map needs a mesh with a uv atlas");
  if (resolution <= 0 || resolution > kMaxTextureResolution) fail("texel map resolution {} out of range", resolution);
  const size_t n = static_cast<size_t>(resolution) * resolution;
  std::vector<std::atomic<uint32_t>> cover(n);
  for (auto& c : cover) c.store(kEmpty, std::memory_order_relaxed);
  const float R = static_cast<float>(resolution);
  // Conservative rasterisation: a texel belongs to every triangle that touches its square, so
  // no chart loses a sliver thinner than a texel. A triangle covering the texel centre takes
  // priority over one that only touches it; ties go to the lower index, whatever the schedule.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.triangles.size(), 1024), [&](const tbb::blocked_range<size_t>&
                                                                                        r) {
    for (size_t f = r.begin(); f < r.end(); ++f) {
      const auto& t = mesh.triangles[f];
      const Vec2 v[3] = {mesh.uvs[t[0]] * R, mesh.uvs[t[1]] * R, mesh.uvs[t[2]] * R};
      const float orient =
          (v[1] - v[0]).x() * (v[2] - v[0]).y() - (v[1] - v[0]).y() * (v[2] - v[0]).x() >= 0 ? 1.0f : -1.0f;
      const int x0 = std::max(0, static_cast<int>(std::floor(std::min({v[0].x(), v[1].x(), v[2].x()}))));
      const int x1 = std::min(resolution - 1, static_cast<int>(std::floor(std::max({v[0].x(), v[1].x(), v[2].x()}))));
      const int y0 = std::max(0, static_cast<int>(std::floor(std::min({v[0].y(), v[1].y(), v[2].y()}))));
      const int y1 = std::min(resolution - 1, static_cast<int>(std::floor(std::max({v[0].y(), v[1].y(), v[2].y()}))));
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          bool touches = true;  // separating axis: each edge's inward normal vs the square's best corner
          for (int e = 0; e < 3 && touches; ++e) {
            const Vec2 d = v[(e + 1) % 3] - v[e];
            const Vec2 inward = orient * Vec2(-d.y(), d.x());
            const Vec2 corner(inward.x() >= 0 ? x + 1.0f : float(x), inward.y() >= 0 ? y + 1.0f : float(y));
            touches = inward.dot(corner - v[e]) >= 0.0f;
          }
          if (!touches) continue;
          const bool centre = barycentricOf(Vec2(x + 0.5f, y + 0.5f), v[0], v[1], v[2]).minCoeff() >= -1e-6f;
          const uint32_t key = static_cast<uint32_t>(f) | (centre ? 0u : kDilated);
          std::atomic<uint32_t>& slot = cover[static_cast<size_t>(y) * resolution + x];
          uint32_t cur = slot.load(std::memory_order_relaxed);
          while (key < cur && !slot.compare_exchange_weak(cur, key)) {
          }
        }
    }
  });
  entries_.resize(n);
  for (size_t i = 0; i < n; ++i) entries_[i] = cover[i].load(std::memory_order_relaxed);
  for (uint32_t e : entries_) covered_ += e != kEmpty && !(e & kDilated);
  // Dilation rings: an empty texel takes the triangle of its first valid neighbour (4-neighbours
  // before diagonals, fixed order), from the previous ring only.
  static const int dx[8] = {1, -1, 0, 0, 1, -1, 1, -1}, dy[8] = {0, 0, 1, -1, 1, 1, -1, -1};
  for (int ring = 0; ring < rings; ++ring) {
    const std::vector<uint32_t> prev = entries_;
    tbb::parallel_for(0, resolution, [&](int y) {
      for (int x = 0; x < resolution; ++x) {
        const size_t i = static_cast<size_t>(y) * resolution + x;
        if (prev[i] != kEmpty) continue;
        for (int k = 0; k < 8; ++k) {
          const int nx = x + dx[k], ny = y + dy[k];
          if (nx < 0 || ny < 0 || nx >= resolution || ny >= resolution) continue;
          const uint32_t e = prev[static_cast<size_t>(ny) * resolution + nx];
          if (e == kEmpty) continue;
          entries_[i] = e | kDilated;
          break;
        }
      }
    });
  }
}

Vec3 TexelMap::barycentrics(const TriangleMesh& mesh, size_t texel) const {
  const auto& t = mesh.triangles[triangle(texel)];
  Vec3 bc = barycentricOf(texelCentreUv(texel), mesh.uvs[t[0]], mesh.uvs[t[1]], mesh.uvs[t[2]]);
  if (!covered(texel)) {
    bc = bc.cwiseMax(0.0f);
    const float sum = bc.sum();
    bc = sum > 0.0f ? Vec3(bc / sum) : Vec3::Constant(1.0f / 3.0f);
  }
  return bc;
}

Vec3 TexelMap::normal(const TriangleMesh& mesh, size_t texel, bool* fellBack) const {
  const size_t f = triangle(texel);
  const auto n = mesh.shadingNormal(f, barycentrics(mesh, texel));
  if (fellBack) *fellBack = !n && !mesh.normals.empty();
  return n ? *n : mesh.faceNormal(f);
}

Vec3 TexelMap::point(const TriangleMesh& mesh, size_t texel) const {
  const auto& t = mesh.triangles[triangle(texel)];
  const Vec3 bc = barycentrics(mesh, texel);
  return bc[0] * mesh.positions[t[0]] + bc[1] * mesh.positions[t[1]] + bc[2] * mesh.positions[t[2]];
}

}  // namespace relume
