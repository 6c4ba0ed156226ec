#include "optim/upsample.h"

#include <tbb/parallel_for.h>

namespace relume {

std::vector<float> upsampleTexels(std::span<const float> parent, const TexelMap& parentMap, const TexelMap& childMap,
                                  const TriangleMesh& mesh, int channels) {
  const int pr = parentMap.resolution(), cr = childMap.resolution();
  const float f = static_cast<float>(cr) / static_cast<float>(pr);
  std::vector<float> child(childMap.texelCount() * channels, 0.0f);
  auto objectOf = [&](const TexelMap& m, size_t t) { return mesh.faceObject[m.triangle(t)]; };
  tbb::parallel_for(size_t{0}, childMap.texelCount(), [&](size_t t) {
    if (!childMap.valid(t)) return;
    const int object = objectOf(childMap, t);
    auto usable = [&](int x, int y) {
      if (x < 0 || y < 0 || x >= pr || y >= pr) return false;
      const size_t p = static_cast<size_t>(y) * pr + x;
      return parentMap.valid(p) && objectOf(parentMap, p) == object;
    };
    const float px = (static_cast<float>(t % cr) + 0.5f) / f - 0.5f,
                py = (static_cast<float>(t / cr) + 0.5f) / f - 0.5f;
    const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
    const float dx = px - x0, dy = py - y0;
    float wsum = 0.0f;
    float* out = &child[t * channels];
    for (int k = 0; k < 4; ++k) {
      const int x = x0 + (k & 1), y = y0 + (k >> 1);
      const float w = ((k & 1) ? dx : 1 - dx) * ((k >> 1) ? dy : 1 - dy);
      if (w <= 0.0f || !usable(x, y)) continue;
      const float* in = &parent[(static_cast<size_t>(y) * pr + x) * channels];
      for (int c = 0; c < channels; ++c) out[c] += w * in[c];
      wsum += w;
    }
    if (wsum > 0.0f) {
      for (int c = 0; c < channels; ++c) out[c] /= wsum;
      return;
    }
    int best = -1;
    float bestD = INFINITY;
    const int cx = static_cast<int>(std::lround(px)), cy = static_cast<int>(std::lround(py));
    for (int y = cy - 2; y <= cy + 2; ++y)
      for (int x = cx - 2; x <= cx + 2; ++x)
        if (const float d = (x - px) * (x - px) + (y - py) * (y - py); d < bestD && usable(x, y))
          bestD = d, best = y * pr + x;
    if (best >= 0)
      for (int c = 0; c < channels; ++c) out[c] = parent[static_cast<size_t>(best) * channels + c];
  });
  return child;
}

}  // namespace relume
