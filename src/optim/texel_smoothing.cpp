#include "optim/texel_smoothing.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/check.h"

namespace relume {

namespace {

// World length of one texel on each triangle: sqrt(3D area / uv area) / resolution (0 when the
// triangle has no uv area).
std::vector<float> texelLengths(const TriangleMesh& mesh, int resolution) {
  std::vector<float> len(mesh.triangles.size(), 0.0f);
  for (size_t f = 0; f < mesh.triangles.size(); ++f) {
    const auto& tri = mesh.triangles[f];
    const Vec3 a = mesh.positions[tri[0]], b = mesh.positions[tri[1]], c = mesh.positions[tri[2]];
    const Vec2 u = mesh.uvs[tri[0]], v = mesh.uvs[tri[1]], w = mesh.uvs[tri[2]];
    const double area3 = 0.5 * (b - a).cross(c - a).norm();
    const double areaUv = 0.5 * std::abs((v - u).x() * (w - u).y() - (v - u).y() * (w - u).x());
    if (areaUv > 0) len[f] = static_cast<float>(std::sqrt(area3 / areaUv) / resolution);
  }
  return len;
}

// Per object, the noise of the guide's log luminance at one texel: adjacent texels (right, below,
// on the same object and next to each other on the surface) differ by noise except at the few
// edges, so the median absolute difference, scaled to a normal's sigma and divided by sqrt(2).
// Objects with fewer than 16 such pairs get infinity (their guide tells nothing apart).
std::vector<float> guideNoise(const TexelMap& map, const TriangleMesh& mesh, const std::vector<float>& logGuide,
                              const std::vector<uint8_t>& used, const std::vector<Vec3>& points,
                              const std::vector<float>& lengths) {
  const int res = map.resolution();
  std::vector<std::vector<float>> diffs(mesh.objectCount);
  for (size_t i = 0; i < used.size(); ++i) {
    if (!used[i]) continue;
    const int object = mesh.faceObject[map.triangle(i)];
    for (const size_t j : {i + 1, i + static_cast<size_t>(res)}) {
      if (j >= used.size() || !used[j] || (j == i + 1 && j % res == 0)) continue;
      if (mesh.faceObject[map.triangle(j)] != object) continue;
      if ((points[j] - points[i]).norm() > 1.5f * lengths[map.triangle(i)]) continue;
      diffs[object].push_back(std::abs(logGuide[j] - logGuide[i]));
    }
  }
  std::vector<float> noise(mesh.objectCount, std::numeric_limits<float>::infinity());
  for (int o = 0; o < mesh.objectCount; ++o) {
    std::vector<float>& d = diffs[o];
    if (d.size() < 16) continue;
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    noise[o] = std::max(1.4826f * d[d.size() / 2] / std::sqrt(2.0f), 1e-6f);
  }
  return noise;
}

}  // namespace

SmoothedTexels smoothTexels(const TexelMap& map, const TriangleMesh& mesh, std::span<const float> values,
                            std::span<const float> standardError, std::span<const uint8_t> eligible,
                            std::span<const float> guide, const TexelSmoothingSettings& s) {
  const size_t n = map.texelCount();
  CHECK(values.size() == 3 * n && standardError.size() == 3 * n && eligible.size() == n);
  CHECK(guide.empty() || guide.size() == 3 * n);
  CHECK(mesh.hasUv() && s.radius >= 1);
  const int res = map.resolution();
  const std::vector<float> lengths = texelLengths(mesh, res);
  // Per texel, whether it takes part: eligible, a known error, a usable guide and texel length;
  // its point, and its guide's log luminance.
  const bool byEdges = !guide.empty();
  std::vector<uint8_t> used(n, 0);
  std::vector<Vec3> points(n);
  std::vector<float> logGuide(byEdges ? n : 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1 << 12), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t t = r.begin(); t < r.end(); ++t) {
      if (!eligible[t] || !map.covered(t) || lengths[map.triangle(t)] <= 0) continue;
      bool ok = true;
      for (int c = 0; c < 3; ++c)
        ok &= standardError[3 * t + c] >= 0 && std::isfinite(standardError[3 * t + c]) &&
              std::isfinite(values[3 * t + c]) &&
              (guide.empty() || guide[3 * t + c] >= s.minGuide);
      if (!ok) continue;
      used[t] = 1;
      points[t] = map.point(mesh, t);
      if (byEdges)
        logGuide[t] = std::log(luminance(Color(guide[3 * t], guide[3 * t + 1], guide[3 * t + 2])));
    }
  });
  SmoothedTexels out{std::vector<float>(values.begin(), values.end()),
                     std::vector<float>(standardError.begin(), standardError.end()), 0};
  const std::vector<float> noise =
      byEdges ? guideNoise(map, mesh, logGuide, used, points, lengths) : std::vector<float>{};
  const float sigma = 0.5f * static_cast<float>(s.radius), reach = static_cast<float>(s.radius) + 0.5f;
  std::atomic<size_t> smoothed{0};
  tbb::parallel_for(tbb::blocked_range<int>(0, res, 8), [&](const tbb::blocked_range<int>& rows) {
    size_t local = 0;
    for (int y = rows.begin(); y < rows.end(); ++y)
      for (int x = 0; x < res; ++x) {
        const size_t i = static_cast<size_t>(y) * res + x;
        if (!used[i]) continue;
        const uint32_t tri = map.triangle(i);
        const int object = mesh.faceObject[tri];
        const float len = lengths[tri];
        float vi[3];
        for (int c = 0; c < 3; ++c) vi[c] = standardError[3 * i + c] * standardError[3 * i + c];
        double wsum = 0, q[3] = {0, 0, 0}, var[3] = {0, 0, 0};
        int neighbours = 0;
        for (int dy = -s.radius; dy <= s.radius; ++dy)
          for (int dx = -s.radius; dx <= s.radius; ++dx) {
            const int xx = x + dx, yy = y + dy;
            if (xx < 0 || yy < 0 || xx >= res || yy >= res) continue;
            const size_t j = static_cast<size_t>(yy) * res + xx;
            if (!used[j] || mesh.faceObject[map.triangle(j)] != object) continue;
            const float d = (points[j] - points[i]).norm() / len;
            if (d > reach) continue;
            float vj[3], z2 = 0, vmean = 0;
            for (int c = 0; c < 3; ++c) {
              vj[c] = standardError[3 * j + c] * standardError[3 * j + c];
              const float diff = values[3 * j + c] - values[3 * i + c];
              z2 += diff * diff / std::max(vi[c] + vj[c], 1e-12f) / 3.0f;
              vmean += vj[c] / 3.0f;
            }
            if (byEdges) {  // the guide's difference in its own standard errors (of a difference: sqrt(2))
              const float dg = (logGuide[j] - logGuide[i]) / noise[object];
              z2 += 0.5f * dg * dg;
            }
            const double w = std::exp(-0.5 * d * d / (sigma * sigma)) / std::max(vmean, 1e-10f) *
                             std::exp(-0.5 * z2 / (s.significance * s.significance));
            if (!(w > 0)) continue;
            wsum += w;
            for (int c = 0; c < 3; ++c) q[c] += w * values[3 * j + c], var[c] += w * w * vj[c];
            neighbours += j != i;
          }
        CHECK(wsum > 0);  // the texel itself is always in
        for (int c = 0; c < 3; ++c) {
          out.values[3 * i + c] = static_cast<float>(q[c] / wsum);
          out.standardError[3 * i + c] = static_cast<float>(std::sqrt(var[c]) / wsum);
        }
        local += neighbours > 0;
      }
    smoothed += local;
  });
  out.smoothed = smoothed;
  return out;
}

}  // namespace relume
