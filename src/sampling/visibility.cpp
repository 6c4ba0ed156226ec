#include "sampling/visibility.h"

#include <algorithm>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstring>
#include <fstream>

#include "core/error.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/input_file.h"

namespace relume {
namespace fs = std::filesystem;

std::optional<Vec2> inView(const Camera& cam, const Vec3& p, const Vec3& n) {
  // Either side: BSDFs are two-sided, so a wall wound away from the room is still seen from it.
  if (!(std::abs(n.dot(cam.position - p)) > 0.0f)) return std::nullopt;  // edge-on; also rejects NaN
  const auto px = cam.project(p);
  if (!px || !(px->x() >= 0.5f && px->y() >= 0.5f && px->x() <= cam.width - 0.5f && px->y() <= cam.height - 0.5f))
    return std::nullopt;
  return px;
}

std::optional<Vec2> observe(const Scene& scene, const Camera& cam, const Vec3& p, const Vec3& n) {
  const auto px = inView(cam, p, n);
  if (!px) return std::nullopt;
  const Vec3 toCam = cam.position - p;
  const float dist = toCam.norm();
  const float tmax = dist - 2 * rayEpsilon(cam.position);
  if (!(tmax > 0.0f)) return std::nullopt;  // a point at the camera's own position
  const Vec3 dir = toCam / dist;
  const Vec3 o = p + rayEpsilon(p) * (n.dot(toCam) > 0.0f ? n : Vec3(-n));
  if (scene.occluded(o, dir, tmax)) return std::nullopt;
  return px;
}

size_t VisibilityIndex::tileOf(size_t texel, int texelResolution) const {
  const int scale = texelResolution / resolution;
  const int x = static_cast<int>(texel % texelResolution) / scale,
            y = static_cast<int>(texel / texelResolution) / scale;
  return static_cast<size_t>(y / tileTexels) * tilesPerSide + x / tileTexels;
}

VisibilityIndex buildVisibilityIndex(const Scene& scene, const TexelMap& map, const std::vector<Frame>& frames,
                                     const std::vector<size_t>& use, int tileTexels, int samplesPerTile) {
  const TriangleMesh& mesh = scene.mesh();
  const int res = map.resolution();
  VisibilityIndex vis;
  vis.resolution = res, vis.tileTexels = tileTexels, vis.tilesPerSide = res / tileTexels;
  const size_t tiles = static_cast<size_t>(vis.tilesPerSide) * vis.tilesPerSide;
  std::vector<std::vector<uint32_t>> perTile(tiles);
  Progress progress("visibility", tiles);
  tbb::parallel_for(size_t{0}, tiles, [&](size_t tile) {
    const int tx = static_cast<int>(tile % vis.tilesPerSide), ty = static_cast<int>(tile / vis.tilesPerSide);
    std::vector<size_t> texels;
    for (int y = ty * tileTexels; y < (ty + 1) * tileTexels; ++y)
      for (int x = tx * tileTexels; x < (tx + 1) * tileTexels; ++x)
        if (map.valid(static_cast<size_t>(y) * res + x)) texels.push_back(static_cast<size_t>(y) * res + x);
    if (!texels.empty()) {
      // Evenly spread test points over the tile's valid texels (deterministic).
      std::vector<std::pair<Vec3, Vec3>> samples;
      const int n = std::min<int>(samplesPerTile, static_cast<int>(texels.size()));
      for (int s = 0; s < n; ++s) {
        const size_t texel = texels[(texels.size() * (2 * s + 1)) / (2 * n)];
        samples.push_back({map.point(mesh, texel), map.normal(mesh, texel)});
      }
      for (size_t k : use)
        for (const auto& [p, nrm] : samples)
          if (observe(scene, frames[k].camera, p, nrm)) {
            perTile[tile].push_back(static_cast<uint32_t>(k));
            break;
          }
    }
    progress.advance();
  });
  vis.offsets.push_back(0);
  for (const auto& f : perTile) {
    vis.frames.insert(vis.frames.end(), f.begin(), f.end());
    vis.offsets.push_back(static_cast<uint32_t>(vis.frames.size()));
  }
  return vis;
}

void VisibilityIndex::write(const fs::path& path) const {
  std::string bytes = "RLMVIS01";
  auto put = [&](const void* p, size_t n) { bytes.append(static_cast<const char*>(p), n); };
  const uint32_t header[4] = {static_cast<uint32_t>(resolution), static_cast<uint32_t>(tileTexels),
                              static_cast<uint32_t>(tilesPerSide), static_cast<uint32_t>(frames.size())};
  put(header, sizeof(header));
  put(offsets.data(), offsets.size() * sizeof(uint32_t));
  put(frames.data(), frames.size() * sizeof(uint32_t));
  writeTextAtomically(path, bytes);
}

VisibilityIndex VisibilityIndex::read(const fs::path& path, size_t frameCount) {
  const std::string file = path.string();
  const std::string bytes = readRegularFile(path, "a relume visibility index");
  if (bytes.size() < 24 || bytes.compare(0, 8, "RLMVIS01") != 0) fail("{}: not a relume visibility index", file);
  uint32_t header[4];
  std::memcpy(header, bytes.data() + 8, sizeof(header));
  // Every number checked here, so tileOf/framesOf can index without checks.
  constexpr uint32_t kMaxResolution = 65536;
  if (header[0] < 1 || header[0] > kMaxResolution || header[1] < 1 || header[1] > header[0] ||
      header[0] % header[1] != 0 || header[2] != header[0] / header[1])
    fail(
        "{}: resolution {}, tile {} texels, {} tiles per side: need resolution in [1, {}] = tile size x tiles per side",
        file, header[0], header[1], header[2], kMaxResolution);
  VisibilityIndex v;
  v.resolution = static_cast<int>(header[0]), v.tileTexels = static_cast<int>(header[1]),
  v.tilesPerSide = static_cast<int>(header[2]);
  const size_t tiles = static_cast<size_t>(v.tilesPerSide) * v.tilesPerSide;
  if (bytes.size() != 24 + (tiles + 1 + header[3]) * sizeof(uint32_t))
    fail("{}: visibility index is truncated or corrupt ({} bytes for {} tiles and {} entries)", file, bytes.size(),
         tiles, header[3]);
  v.offsets.resize(tiles + 1);
  v.frames.resize(header[3]);
  std::memcpy(v.offsets.data(), bytes.data() + 24, v.offsets.size() * sizeof(uint32_t));
  // Guarded: an index with no entries has frames.data() == nullptr, and memcpy from/to null is undefined even for 0
  // bytes.
  if (!v.frames.empty())
    std::memcpy(v.frames.data(), bytes.data() + 24 + v.offsets.size() * sizeof(uint32_t),
                v.frames.size() * sizeof(uint32_t));
  if (v.offsets.front() != 0 || v.offsets.back() != v.frames.size() ||
      !std::is_sorted(v.offsets.begin(), v.offsets.end()))
    fail("{}: visibility index offsets must rise from 0 to the entry count {}", file, v.frames.size());
  for (const uint32_t f : v.frames)
    if (f >= frameCount) fail("{}: visibility index names frame {}, the capture has {}", file, f, frameCount);
  return v;
}

}  // namespace relume
