#include "scene/segmentation.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numeric>
#include <tuple>
#include <unordered_map>

#include "core/check.h"
#include "core/error.h"
#include "io/atomic_file.h"

namespace relume {
namespace {

// Vertices at bit-identical positions become one (meshes repeat a vertex at every uv or normal seam).
std::vector<uint32_t> weldVertices(const TriangleMesh& mesh) {
  struct Key {
    uint32_t x, y, z;
    bool operator==(const Key& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      return (static_cast<size_t>(k.x) * 73856093u) ^ (static_cast<size_t>(k.y) * 19349663u) ^
             (static_cast<size_t>(k.z) * 83492791u);
    }
  };
  std::unordered_map<Key, uint32_t, KeyHash> ids;
  ids.reserve(mesh.positions.size());
  std::vector<uint32_t> welded(mesh.positions.size());
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    Key k{};
    const Vec3& p = mesh.positions[v];
    // +0.0f: -0 and +0 are the same position.
    const float x = p.x() + 0.0f, y = p.y() + 0.0f, z = p.z() + 0.0f;
    std::memcpy(&k.x, &x, 4), std::memcpy(&k.y, &y, 4), std::memcpy(&k.z, &z, 4);
    welded[v] = ids.emplace(k, static_cast<uint32_t>(ids.size())).first->second;
  }
  return welded;
}

// Pairs of faces that share an edge of the welded mesh. Around a non-manifold edge the faces are
// chained in index order, so they still end up connected.
std::vector<std::pair<uint32_t, uint32_t>> adjacentFaces(const TriangleMesh& mesh) {
  const std::vector<uint32_t> welded = weldVertices(mesh);
  std::vector<std::tuple<uint32_t, uint32_t, uint32_t>> edges;
  edges.reserve(3 * mesh.triangles.size());
  for (size_t f = 0; f < mesh.triangles.size(); ++f)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = welded[mesh.triangles[f][e]], b = welded[mesh.triangles[f][(e + 1) % 3]];
      if (a != b) edges.emplace_back(std::min(a, b), std::max(a, b), static_cast<uint32_t>(f));
    }
  std::sort(edges.begin(), edges.end());
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  for (size_t i = 1; i < edges.size(); ++i)
    if (std::get<0>(edges[i]) == std::get<0>(edges[i - 1]) && std::get<1>(edges[i]) == std::get<1>(edges[i - 1]) &&
        std::get<2>(edges[i]) != std::get<2>(edges[i - 1]))
      pairs.emplace_back(std::get<2>(edges[i - 1]), std::get<2>(edges[i]));
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

// Face normals averaged over their neighbours (area-weighted, two rounds, only neighbours within
// 60 degrees so creases stay sharp): a scan's vertex noise tilts single small faces by tens of
// degrees, which a crease test on raw normals would take for edges. Orientation is ignored (meshes
// often have inconsistent winding).
std::vector<Vec3> smoothedNormals(const TriangleMesh& mesh, const std::vector<std::pair<uint32_t, uint32_t>>& pairs) {
  const size_t faces = mesh.triangles.size();
  std::vector<Vec3> raw(faces), smooth(faces);
  for (size_t f = 0; f < faces; ++f) raw[f] = mesh.faceNormal(f);
  smooth = raw;
  constexpr float kNeighbourCos = 0.5f;
  for (int round = 0; round < 2; ++round) {
    std::vector<Vec3> sum(faces);
    for (size_t f = 0; f < faces; ++f) sum[f] = mesh.faceArea[f] * smooth[f];
    for (const auto& [a, b] : pairs) {
      if (std::abs(raw[a].dot(raw[b])) < kNeighbourCos) continue;
      const float sign = smooth[a].dot(smooth[b]) < 0 ? -1.0f : 1.0f;
      sum[a] += sign * mesh.faceArea[b] * smooth[b];
      sum[b] += sign * mesh.faceArea[a] * smooth[a];
    }
    for (size_t f = 0; f < faces; ++f) {
      const float n = sum[f].norm();
      smooth[f] = n > 0 && std::isfinite(n) ? Vec3(sum[f] / n) : raw[f];
    }
  }
  return smooth;
}

// Faces and regions seen clipped more often than this show floors, not values.
constexpr double kMostlyClipped = 0.5;
// Regions of at least this many faces have main normals stable enough to compare.
constexpr size_t kCreaseFaces = 16;

class Regions {
 public:
  Regions(const TriangleMesh& mesh, const std::vector<FaceAppearance>& appearance)
      : parent_(mesh.triangles.size()), stats_(mesh.triangles.size()) {
    std::iota(parent_.begin(), parent_.end(), 0u);
    for (size_t f = 0; f < parent_.size(); ++f) {
      Stats& s = stats_[f];
      s.area = mesh.faceArea[f];
      const Eigen::Vector3d n = mesh.faceNormal(f).cast<double>();
      s.normalTensor = s.area * n * n.transpose();
      if (!appearance[f].observed) continue;
      s.information = 1.0 / std::max(static_cast<double>(appearance[f].logError.square().mean()), 1e-8);
      s.observedArea = s.area;
      s.logSum = s.area * appearance[f].logRadiance.cast<double>();
      s.clipSum = s.area * appearance[f].clippedFraction;
    }
  }
  uint32_t find(uint32_t f) {
    while (parent_[f] != f) f = parent_[f] = parent_[parent_[f]];
    return f;
  }
  void join(uint32_t a, uint32_t b) {
    a = find(a), b = find(b);
    DCHECK(a != b);
    if (stats_[a].area < stats_[b].area || (stats_[a].area == stats_[b].area && b < a)) std::swap(a, b);
    parent_[b] = a;
    Stats& s = stats_[a];
    const Stats& t = stats_[b];
    s.area += t.area, s.observedArea += t.observedArea, s.logSum += t.logSum, s.clipSum += t.clipSum;
    s.normalTensor += t.normalTensor, s.information += t.information, s.faces += t.faces;
  }
  // Whether two regions meet at a crease: B's faces are, on average, more than the crease angle
  // away from A's main normal, or the other way round (cos2: the crease angle's squared cosine).
  // Orientation is ignored (area-weighted second moments of the normals).
  bool creased(uint32_t a, uint32_t b, double cos2) const {
    const auto alignment = [&](uint32_t x, uint32_t y) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> e;
      e.computeDirect(stats_[x].normalTensor);
      const Eigen::Vector3d axis = e.eigenvectors().col(2);
      return axis.dot(stats_[y].normalTensor * axis) / stats_[y].area;
    };
    return std::min(alignment(a, b), alignment(b, a)) < cos2;
  }
  double area(uint32_t root) const { return stats_[root].area; }
  size_t faces(uint32_t root) const { return stats_[root].faces; }
  bool observed(uint32_t root) const { return stats_[root].observedArea > 0; }
  Eigen::Array3d meanLog(uint32_t root) const { return stats_[root].logSum / stats_[root].observedArea; }
  double meanClip(uint32_t root) const { return stats_[root].clipSum / stats_[root].observedArea; }
  // Standard error of meanLog, from its faces' errors as if independent.
  double logError(uint32_t root) const { return 1.0 / std::sqrt(stats_[root].information); }
  double meanLogLuminance(uint32_t root) const {
    const Eigen::Array3d c = meanLog(root).exp();
    return std::log(0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]);
  }
  // The largest per-channel difference of the two regions' mean log radiance (0 if either was never
  // seen, or both mostly clipped).
  double distance(uint32_t a, uint32_t b) const {
    if (!observed(a) || !observed(b) || std::min(meanClip(a), meanClip(b)) > kMostlyClipped) return 0;
    return (meanLog(a) - meanLog(b)).abs().maxCoeff();
  }
  size_t size() const { return parent_.size(); }

 private:
  struct Stats {
    double area = 0, observedArea = 0, clipSum = 0, information = 0;  // information: sum of 1 / error^2
    size_t faces = 1;
    Eigen::Array3d logSum = Eigen::Array3d::Zero();
    Eigen::Matrix3d normalTensor = Eigen::Matrix3d::Zero();  // sum of area n n^T
  };
  std::vector<uint32_t> parent_;
  std::vector<Stats> stats_;
};

size_t countRoots(Regions& r) {
  size_t n = 0;
  for (uint32_t f = 0; f < r.size(); ++f) n += r.find(f) == f;
  return n;
}

void joinAll(Regions& r, const std::vector<std::pair<uint32_t, uint32_t>>& pairs) {
  for (const auto& [a, b] : pairs)
    if (r.find(a) != r.find(b)) r.join(a, b);
}

}  // namespace

std::vector<uint32_t> connectedComponents(const TriangleMesh& mesh) {
  Regions components(mesh, std::vector<FaceAppearance>(mesh.triangles.size()));
  joinAll(components, adjacentFaces(mesh));
  std::vector<uint32_t> id(mesh.triangles.size(), UINT32_MAX), out(mesh.triangles.size());
  uint32_t next = 0;
  for (uint32_t f = 0; f < mesh.triangles.size(); ++f) {
    const uint32_t r = components.find(f);
    if (id[r] == UINT32_MAX) id[r] = next++;
    out[f] = id[r];
  }
  return out;
}

Segmentation segmentMesh(const TriangleMesh& mesh, const std::vector<FaceAppearance>& appearance,
                         const SegmentationOptions& o) {
  CHECK(appearance.size() == mesh.triangles.size());
  const std::vector<std::pair<uint32_t, uint32_t>> pairs = adjacentFaces(mesh);
  const std::vector<Vec3> normal = smoothedNormals(mesh, pairs);
  Segmentation seg;
  {
    Regions components(mesh, appearance);
    joinAll(components, pairs);
    seg.components = countRoots(components);
  }

  // Steps 1-3: the pairs that may join, most similar first.
  const float creaseCos = std::cos(o.creaseDegrees * kPi / 180.0f), edgeLog = std::log(o.edgeContrast);
  std::vector<std::pair<float, uint32_t>> candidates;
  for (uint32_t i = 0; i < pairs.size(); ++i) {
    const auto [a, b] = pairs[i];
    if (std::abs(normal[a].dot(normal[b])) < creaseCos) continue;
    const FaceAppearance &fa = appearance[a], &fb = appearance[b];
    float difference = 0;
    if (fa.observed && fb.observed && std::min(fa.clippedFraction, fb.clippedFraction) <= kMostlyClipped) {
      if (std::abs(fa.clippedFraction - fb.clippedFraction) > o.clipSplit) continue;
      const Color d = (fa.logRadiance - fb.logRadiance).abs();
      const Color noise = o.significance * (fa.logError.square() + fb.logError.square()).sqrt();
      if ((d > noise.max(edgeLog)).any()) continue;
      difference = d.maxCoeff();
    }
    candidates.emplace_back(difference, i);
  }
  std::sort(candidates.begin(), candidates.end());
  Regions regions(mesh, appearance);
  double total = 0;
  for (float a : mesh.faceArea) total += a;
  const double minArea = o.minAreaFraction * total, brighter = std::log(o.keepBrighter);
  const double regionLog = std::log(o.regionContrast);
  const double regionCreaseCos2 = std::pow(std::cos(o.regionCreaseDegrees * kPi / 180.0), 2);
  for (const auto& [difference, i] : candidates) {
    const uint32_t a = regions.find(pairs[i].first), b = regions.find(pairs[i].second);
    if (a == b) continue;
    if (regions.observed(a) && regions.observed(b) &&
        (regions.distance(a, b) > regionLog || std::abs(regions.meanClip(a) - regions.meanClip(b)) > o.clipSplit))
      continue;
    // Two regions past the small size, with enough faces to average their noise, that meet at a
    // crease noisy faces blurred into a ramp of small steps stay apart. (A region growing face by
    // face round such a crease is not stopped: it would cut every sphere into caps.)
    const auto settled = [&](uint32_t r) { return regions.area(r) >= minArea && regions.faces(r) >= kCreaseFaces; };
    if (settled(a) && settled(b) && regions.creased(a, b, regionCreaseCos2)) continue;
    regions.join(a, b);
  }
  seg.grownRegions = countRoots(regions);

  // Step 4: small regions into their most similar neighbour, smallest first, each region at most
  // once per round (its neighbours' statistics are the round's), until a round merges nothing.
  std::vector<char> kept(mesh.triangles.size(), 0);
  bool merged = true;
  std::vector<uint32_t> isolated;
  while (merged) {
    merged = false;
    std::vector<std::pair<uint32_t, uint32_t>> links;
    for (const auto& [a, b] : pairs) {
      const uint32_t ra = regions.find(a), rb = regions.find(b);
      if (ra != rb) links.emplace_back(ra, rb), links.emplace_back(rb, ra);
    }
    std::sort(links.begin(), links.end());
    links.erase(std::unique(links.begin(), links.end()), links.end());
    std::vector<std::pair<double, uint32_t>> small;
    for (uint32_t f = 0; f < regions.size(); ++f)
      if (regions.find(f) == f && regions.area(f) < minArea && !kept[f]) small.emplace_back(regions.area(f), f);
    std::sort(small.begin(), small.end());
    std::vector<char> touched(mesh.triangles.size(), 0);
    isolated.clear();
    for (const auto& [area, r] : small) {
      if (touched[r]) continue;
      auto it = std::lower_bound(links.begin(), links.end(), std::make_pair(r, 0u));
      uint32_t best = r;
      double bestDistance = INFINITY;
      for (; it != links.end() && it->first == r; ++it) {
        const double d = regions.distance(r, it->second);
        if (d < bestDistance || (d == bestDistance && regions.area(it->second) > regions.area(best))) {
          best = it->second;
          bestDistance = d;
        }
      }
      if (best == r) {
        isolated.push_back(r);
        continue;
      }
      if (touched[best]) continue;  // its statistics changed this round: next round
      const double noise = o.significance * std::hypot(regions.logError(r), regions.logError(best));
      if (regions.observed(r) && regions.observed(best) &&
          (regions.meanLogLuminance(r) - regions.meanLogLuminance(best) > std::max(brighter, noise) ||
           regions.meanClip(r) - regions.meanClip(best) > o.clipSplit)) {
        kept[r] = 1;
        ++seg.keptSmallBright;
        continue;
      }
      regions.join(r, best);
      touched[regions.find(r)] = 1, touched[r] = 1, touched[best] = 1;
      ++seg.mergedSmall;
      merged = true;
    }
  }
  seg.isolatedSmall = isolated.size();

  std::vector<int32_t> id(mesh.triangles.size(), -1);
  seg.faceObject.resize(mesh.triangles.size());
  for (uint32_t f = 0; f < mesh.triangles.size(); ++f) {
    const uint32_t r = regions.find(f);
    if (id[r] < 0) id[r] = seg.objects++;
    seg.faceObject[f] = id[r];
  }
  return seg;
}

namespace {
constexpr char kFaceObjectsMagic[8] = {'R', 'S', 'E', 'G', 'M', 'N', 'T', '1'};
}  // namespace

void writeFaceObjects(const std::filesystem::path& file, const std::vector<int32_t>& faceObject) {
  writeAtomically(file, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    const uint64_t n = faceObject.size();
    out.write(kFaceObjectsMagic, sizeof kFaceObjectsMagic);
    out.write(reinterpret_cast<const char*>(&n), sizeof n);
    out.write(reinterpret_cast<const char*>(faceObject.data()), static_cast<std::streamsize>(n * sizeof(int32_t)));
    if (!out) fail("{}: could not be written", file.string());
  });
}

std::vector<int32_t> readFaceObjects(const std::filesystem::path& file, size_t faces) {
  std::ifstream in(file, std::ios::binary);
  char magic[sizeof kFaceObjectsMagic] = {};
  uint64_t n = 0;
  in.read(magic, sizeof magic);
  in.read(reinterpret_cast<char*>(&n), sizeof n);
  if (!in || std::memcmp(magic, kFaceObjectsMagic, sizeof magic) != 0 || n != faces || faces == 0)
    fail("{}: not the segmentation of this mesh ({} faces; rerun prepare with --force)", file.string(), faces);
  std::vector<int32_t> ids(n);
  in.read(reinterpret_cast<char*>(ids.data()), static_cast<std::streamsize>(n * sizeof(int32_t)));
  if (!in) fail("{}: truncated (rerun prepare with --force)", file.string());
  if (in.peek() != std::char_traits<char>::eof())
    fail("{}: longer than the segmentation of {} faces (rerun prepare with --force)", file.string(), faces);
  for (int32_t id : ids)
    if (id < 0 || static_cast<size_t>(id) >= faces) fail("{}: object id {} out of range", file.string(), id);
  return ids;
}

}  // namespace relume
