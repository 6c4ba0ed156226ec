#include "scene/atlas.h"

#include <Eigen/SparseCholesky>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <map>
#include <numeric>
#include <unordered_map>

#include "core/system.h"
#include "scene/atlas_internal.h"

namespace relume {
namespace {

using namespace atlas_detail;

using Vec2d = Eigen::Vector2d;

// Separating-axis test on the 6 edge normals; touching triangles do not overlap.
bool trianglesOverlap(const std::array<Vec2d, 3>& a, const std::array<Vec2d, 3>& b, double eps) {
  for (const auto* tri : {&a, &b}) {
    const double orient = cross2((*tri)[0], (*tri)[1], (*tri)[2]) >= 0 ? 1.0 : -1.0;
    for (int e = 0; e < 3; ++e) {
      const Vec2d p = (*tri)[e], q = (*tri)[(e + 1) % 3];
      const Vec2d n = orient * Vec2d(q.y() - p.y(), p.x() - q.x());  // outward normal
      double maxOwn = -INFINITY, minOther = INFINITY;
      for (const Vec2d& v : *tri) maxOwn = std::max(maxOwn, n.dot(v - p));
      const auto* other = tri == &a ? &b : &a;
      for (const Vec2d& v : *other) minOther = std::min(minOther, n.dot(v - p));
      if (minOther >= maxOwn - eps * n.norm()) return false;
    }
  }
  return true;
}

// Pairs of overlapping triangles among `faces` with 2D corners `uvOf(face, k)`, found through a
// uniform grid over their bounding boxes; stops after `stopAfter`.
template <typename UvOf>
size_t countOverlaps(const std::vector<uint32_t>& faces, const UvOf& uvOf, size_t stopAfter) {
  if (faces.size() < 2) return 0;
  Eigen::AlignedBox2d all;
  std::vector<Eigen::AlignedBox2d> boxes(faces.size());
  for (size_t i = 0; i < faces.size(); ++i) {
    for (int k = 0; k < 3; ++k) boxes[i].extend(uvOf(faces[i], k));
    all.extend(boxes[i]);
  }
  const double extent = std::max(all.sizes().maxCoeff(), 1e-30);
  const int n = std::clamp(static_cast<int>(std::sqrt(static_cast<double>(faces.size()))), 1, 4096);
  const double cell = extent / n * (1 + 1e-9);
  auto cellOf = [&](double v, double lo) { return std::clamp(static_cast<int>((v - lo) / cell), 0, n - 1); };
  std::unordered_map<int64_t, std::vector<uint32_t>> grid;
  for (uint32_t i = 0; i < faces.size(); ++i)
    for (int y = cellOf(boxes[i].min().y(), all.min().y()); y <= cellOf(boxes[i].max().y(), all.min().y()); ++y)
      for (int x = cellOf(boxes[i].min().x(), all.min().x()); x <= cellOf(boxes[i].max().x(), all.min().x()); ++x)
        grid[static_cast<int64_t>(y) * n + x].push_back(i);
  const double eps = 1e-9 * extent;
  size_t found = 0;
  for (const auto& [key, members] : grid) {
    const int cx = static_cast<int>(key % n), cy = static_cast<int>(key / n);
    for (size_t a = 0; a < members.size(); ++a)
      for (size_t b = a + 1; b < members.size(); ++b) {
        const uint32_t i = members[a], j = members[b];
        const Eigen::AlignedBox2d both = boxes[i].intersection(boxes[j]);
        if (both.isEmpty()) continue;
        // Test each pair once: in the cell holding the lower-left corner of the boxes' overlap.
        if (cellOf(both.min().x(), all.min().x()) != cx || cellOf(both.min().y(), all.min().y()) != cy) continue;
        const std::array<Vec2d, 3> ta{uvOf(faces[i], 0), uvOf(faces[i], 1), uvOf(faces[i], 2)};
        const std::array<Vec2d, 3> tb{uvOf(faces[j], 0), uvOf(faces[j], 1), uvOf(faces[j], 2)};
        if (trianglesOverlap(ta, tb, eps) && ++found >= stopAfter) return found;
      }
  }
  return found;
}

void collectVertices(const TriangleMesh& m, Chart& c) {
  c.vertices.clear();
  c.local.clear();
  for (uint32_t f : c.faces)
    for (int k = 0; k < 3; ++k)
      if (c.local.emplace(m.triangles[f][k], static_cast<int>(c.vertices.size())).second)
        c.vertices.push_back(m.triangles[f][k]);
}

void planarProjection(const TriangleMesh& m, Chart& c, const Vec3& axis) {
  const ShadingFrame frame(axis.normalized());
  c.uv.resize(c.vertices.size());
  for (size_t i = 0; i < c.vertices.size(); ++i) {
    const Vec3& p = m.positions[c.vertices[i]];
    c.uv[i] = Vec2d(p.dot(frame.s), p.dot(frame.t));
  }
}

constexpr double kMaxStretch = 1.1;

// Least-squares conformal map (Levy et al. 2002) with the two farthest vertices pinned; false if
// it flips a face, spreads absurdly, or stretches more than kMaxStretch at its 95th percentile.
bool lscm(const TriangleMesh& m, Chart& c) {
  const int nv = static_cast<int>(c.vertices.size());
  if (nv < 3) return false;
  int pinA = 0, pinB = 0;
  {
    const Vec3 p0 = m.positions[c.vertices[0]];
    float best = -1;
    for (int i = 0; i < nv; ++i)
      if (float d = (m.positions[c.vertices[i]] - p0).squaredNorm(); d > best) best = d, pinA = i;
    best = -1;
    for (int i = 0; i < nv; ++i)
      if (float d = (m.positions[c.vertices[i]] - m.positions[c.vertices[pinA]]).squaredNorm(); d > best)
        best = d, pinB = i;
  }
  if (pinA == pinB) return false;
  const double dist = (m.positions[c.vertices[pinA]] - m.positions[c.vertices[pinB]]).cast<double>().norm();
  // Unknowns: (u, v) of every vertex except the pins -> columns 2*free.
  std::vector<int> column(nv, -1);
  int nFree = 0;
  for (int i = 0; i < nv; ++i)
    if (i != pinA && i != pinB) column[i] = nFree++;
  const Vec2d pinned[2] = {Vec2d(0, 0), Vec2d(dist, 0)};
  std::vector<Eigen::Triplet<double>> trip;
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(2 * static_cast<Eigen::Index>(c.faces.size()));
  for (size_t t = 0; t < c.faces.size(); ++t) {
    const auto& tri = m.triangles[c.faces[t]];
    const Vec3d p0 = m.positions[tri[0]].cast<double>(), p1 = m.positions[tri[1]].cast<double>(),
                p2 = m.positions[tri[2]].cast<double>();
    const Vec3d ex = (p1 - p0).normalized(), n = (p1 - p0).cross(p2 - p0);
    const double area2 = n.norm();
    if (!(area2 > 0)) continue;
    const Vec3d ey = n.normalized().cross(ex);
    const Vec2d q[3] = {Vec2d(0, 0), Vec2d((p1 - p0).dot(ex), 0), Vec2d((p2 - p0).dot(ex), (p2 - p0).dot(ey))};
    const double s = 1.0 / std::sqrt(area2);
    for (int j = 0; j < 3; ++j) {
      const Vec2d w = (q[(j + 2) % 3] - q[(j + 1) % 3]) * s;  // W_j = a + i b
      const int vi = c.local.at(tri[j]);
      const int re = static_cast<int>(2 * t), im = re + 1;
      if (column[vi] >= 0) {
        const int cu = 2 * column[vi], cv = cu + 1;
        trip.emplace_back(re, cu, w.x()), trip.emplace_back(re, cv, -w.y());
        trip.emplace_back(im, cu, w.y()), trip.emplace_back(im, cv, w.x());
      } else {
        const Vec2d pin = pinned[vi == pinA ? 0 : 1];
        rhs[re] -= w.x() * pin.x() - w.y() * pin.y();
        rhs[im] -= w.y() * pin.x() + w.x() * pin.y();
      }
    }
  }
  Eigen::SparseMatrix<double> A(2 * static_cast<Eigen::Index>(c.faces.size()), 2 * nFree);
  A.setFromTriplets(trip.begin(), trip.end());
  const Eigen::SparseMatrix<double> AtA = A.transpose() * A;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(AtA);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::VectorXd x = solver.solve(A.transpose() * rhs);
  if (solver.info() != Eigen::Success || !x.allFinite()) return false;
  c.uv.resize(nv);
  for (int i = 0; i < nv; ++i)
    c.uv[i] = column[i] >= 0 ? Vec2d(x[2 * column[i]], x[2 * column[i] + 1]) : pinned[i == pinA ? 0 : 1];
  // Reject maps with flipped triangles; rescale to the chart's 3D area (metric units).
  double uvArea = 0, area = 0;
  int positive = 0;
  for (uint32_t f : c.faces) {
    const auto& tri = m.triangles[f];
    const double a = cross2(c.uv[c.local.at(tri[0])], c.uv[c.local.at(tri[1])], c.uv[c.local.at(tri[2])]);
    positive += a > 0;
    uvArea += std::abs(a) * 0.5;
    area += m.faceArea[f];
  }
  if (positive != 0 && positive != static_cast<int>(c.faces.size())) return false;
  // An ill-conditioned solve can spread a chart over a huge area while keeping every face unflipped:
  // reject maps whose faces' uv-to-3D area ratios differ by more than 1e4.
  double minRatio = INFINITY, maxRatio = 0;
  for (uint32_t f : c.faces) {
    const auto& tri = m.triangles[f];
    const double ratio =
        std::abs(cross2(c.uv[c.local.at(tri[0])], c.uv[c.local.at(tri[1])], c.uv[c.local.at(tri[2])])) / m.faceArea[f];
    minRatio = std::min(minRatio, ratio), maxRatio = std::max(maxRatio, ratio);
  }
  if (!(maxRatio <= 1e4 * minRatio)) return false;
  // Conformal maps stretch area on curved charts: keep the chart's 95th percentile of the per-face
  // stretch (as AtlasReport measures it) within kMaxStretch, or let the caller project or split.
  const double meanRatio = uvArea / area;
  std::vector<double> stretch;
  for (uint32_t f : c.faces) {
    const auto& tri = m.triangles[f];
    const double ratio =
        std::abs(cross2(c.uv[c.local.at(tri[0])], c.uv[c.local.at(tri[1])], c.uv[c.local.at(tri[2])])) /
        (2 * m.faceArea[f]);
    stretch.push_back(std::sqrt(ratio / meanRatio));
  }
  std::nth_element(stretch.begin(), stretch.begin() + static_cast<long>(stretch.size() * 19 / 20), stretch.end());
  if (stretch[stretch.size() * 19 / 20] > kMaxStretch) return false;
  if (positive == 0)
    for (Vec2d& p : c.uv) p.y() = -p.y();
  const double scale = std::sqrt(area / std::max(uvArea, 1e-300));
  for (Vec2d& p : c.uv) p *= scale;
  return true;
}

}  // namespace

namespace atlas_detail {

// Maps a chart to the plane in metres: projection on its mean plane when it is near-planar by area
// (noisy scans have a few steep faces on flat walls, which a projection handles with less
// distortion than a conformal map with two pins), a least-squares conformal map otherwise, and the
// projection again if that map flips a face and every face is within 78 degrees of the mean normal
// (so the projection cannot flip one). False when the chart has no map without flips or overlaps.
bool parameterise(const TriangleMesh& m, const std::vector<Vec3>& normals, float cosPlanar, Chart& c) {
  collectVertices(m, c);
  Vec3 sum = Vec3::Zero();
  double area = 0;
  for (uint32_t f : c.faces) sum += m.faceArea[f] * normals[f], area += m.faceArea[f];
  const Vec3 axis = sum.normalized();
  double alignedArea = 0;
  float minCos = 1;
  for (uint32_t f : c.faces)
    alignedArea += m.faceArea[f] * normals[f].dot(axis), minCos = std::min(minCos, normals[f].dot(axis));
  c.lscm = false;
  if (alignedArea < cosPlanar * area && lscm(m, c)) {
    c.lscm = true;
  } else if (minCos >= 0.2f) {
    planarProjection(m, c, axis);
  } else {
    return false;
  }
  return c.faces.size() == 1 ||
         countOverlaps(
             c.faces, [&](uint32_t f, int k) { return c.uv[c.local.at(m.triangles[f][k])]; }, 1) == 0;
}

// Rotates the chart to its minimum-area bounding rectangle (rotating calipers on the hull), puts
// it at the origin, and makes it wider than tall.
void orientChart(Chart& c) {
  std::vector<Vec2d> pts = c.uv;
  std::sort(pts.begin(), pts.end(),
            [](const Vec2d& a, const Vec2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  std::vector<Vec2d> hull;
  for (int pass = 0; pass < 2; ++pass) {
    const size_t start = hull.size();
    for (const Vec2d& p : pts) {
      while (hull.size() >= start + 2 && cross2(hull[hull.size() - 2], hull.back(), p) <= 0) hull.pop_back();
      hull.push_back(p);
    }
    hull.pop_back();
    std::reverse(pts.begin(), pts.end());
  }
  double bestArea = INFINITY, bestAngle = 0;
  for (size_t i = 0; i < std::max<size_t>(hull.size(), 1); ++i) {
    const double angle = hull.size() < 2 ? 0.0
                                         : std::atan2(hull[(i + 1) % hull.size()].y() - hull[i].y(),
                                                      hull[(i + 1) % hull.size()].x() - hull[i].x());
    const double cs = std::cos(-angle), sn = std::sin(-angle);
    Eigen::AlignedBox2d box;
    for (const Vec2d& p : hull) box.extend(Vec2d(cs * p.x() - sn * p.y(), sn * p.x() + cs * p.y()));
    if (box.volume() < bestArea - 1e-15) bestArea = box.volume(), bestAngle = angle;
  }
  const double cs = std::cos(-bestAngle), sn = std::sin(-bestAngle);
  Eigen::AlignedBox2d box;
  for (Vec2d& p : c.uv) {
    p = Vec2d(cs * p.x() - sn * p.y(), sn * p.x() + cs * p.y());
    box.extend(p);
  }
  const bool swap = box.sizes().y() > box.sizes().x();
  for (Vec2d& p : c.uv) {
    p -= box.min();
    if (swap) p = Vec2d(p.y(), p.x());
  }
}

// The chart of a subset of `parent`'s faces with the parent's map (a part of a map without flips or
// overlaps has none either), oriented again.
Chart subChart(const TriangleMesh& m, const Chart& parent, std::vector<uint32_t> faces) {
  Chart c;
  c.faces = std::move(faces);
  c.lscm = parent.lscm, c.cone = parent.cone;
  collectVertices(m, c);
  c.uv.resize(c.vertices.size());
  for (size_t v = 0; v < c.vertices.size(); ++v) c.uv[v] = parent.uv[parent.local.at(c.vertices[v])];
  orientChart(c);
  return c;
}

namespace {

double uvArea(const TriangleMesh& m, const Chart& c) {
  double a = 0;
  for (uint32_t f : c.faces) {
    const auto& t = m.triangles[f];
    a += 0.5 * std::abs(cross2(c.uv[c.local.at(t[0])], c.uv[c.local.at(t[1])], c.uv[c.local.at(t[2])]));
  }
  return a;
}

}  // namespace

// A chart filling less than kMinHollowFill of its (oriented) box wastes the rest: the packer places
// footprints on a height map, so nothing fills a frame's inside. Real interiors are full of such
// rings (picture and window frames, coffered ceilings, inlay lines around a floor). Such a chart
// with a box over 64 texels at `density` is cut into straight parts: the components of faces whose
// longest uv edges run within 15 degrees of their neighbour's; a part that is still hollow becomes
// one chart per face. Empty when the chart is fine as it is.
std::vector<Chart> splitHollow(const TriangleMesh& m, const Topology& topo, const Chart& c, double density) {
  constexpr double kMinHollowFill = 0.4, kMinBoxTexels = 64, kMaxTurnDegrees = 15;
  auto hollow = [&](const Chart& part) {
    Eigen::AlignedBox2d box;
    for (const Vec2d& p : part.uv) box.extend(p);
    return part.faces.size() > 1 && box.volume() * density * density > kMinBoxTexels &&
           uvArea(m, part) < kMinHollowFill * box.volume();
  };
  if (!hollow(c)) return {};
  std::unordered_map<uint32_t, uint32_t> index;   // face -> position in c.faces
  std::vector<double> direction(c.faces.size());  // of the longest uv edge, in [0, pi)
  for (uint32_t i = 0; i < c.faces.size(); ++i) {
    index[c.faces[i]] = i;
    const auto& t = m.triangles[c.faces[i]];
    Vec2d longest = Vec2d::Zero();
    for (int k = 0; k < 3; ++k)
      if (const Vec2d e = c.uv[c.local.at(t[(k + 1) % 3])] - c.uv[c.local.at(t[k])];
          e.squaredNorm() > longest.squaredNorm())
        longest = e;
    direction[i] = std::fmod(std::atan2(longest.y(), longest.x()) + kPi, kPi);
  }
  std::vector<uint32_t> parent(c.faces.size());
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  const double maxTurn = kMaxTurnDegrees * kPi / 180;
  for (uint32_t i = 0; i < c.faces.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const int32_t g = topo.neighbour[c.faces[i]][k];
      const auto it = g < 0 ? index.end() : index.find(static_cast<uint32_t>(g));
      if (it == index.end()) continue;
      const double turn = std::abs(direction[i] - direction[it->second]);
      if (std::min(turn, kPi - turn) < maxTurn) parent[root(i)] = root(it->second);
    }
  std::map<uint32_t, std::vector<uint32_t>> parts;  // by root: ordered, so deterministic
  for (uint32_t i = 0; i < c.faces.size(); ++i) parts[root(i)].push_back(c.faces[i]);
  std::vector<Chart> out;
  for (auto& [r, faces] : parts) {
    Chart part = subChart(m, c, std::move(faces));
    if (!hollow(part)) {
      out.push_back(std::move(part));
      continue;
    }
    for (uint32_t f : part.faces) out.push_back(subChart(m, part, {f}));
  }
  return out;
}

// The fold test on a chart's stored uvs: its faces must all keep one orientation and not overlap.
bool foldsInFloat(const TriangleMesh& m, const Chart& c, const std::vector<Vec2>& uv) {
  if (c.faces.size() == 1) return false;
  auto uvOf = [&](uint32_t f, int k) { return Vec2d(uv[c.local.at(m.triangles[f][k])].cast<double>()); };
  int positive = 0;
  for (uint32_t f : c.faces) positive += cross2(uvOf(f, 0), uvOf(f, 1), uvOf(f, 2)) > 0;
  return (positive != 0 && positive != static_cast<int>(c.faces.size())) || countOverlaps(c.faces, uvOf, 1) > 0;
}

// Report of the charting and packing: chart counts, the shared blocks and the share of the surface
// in them, the density.
void reportCharts(AtlasState& s, const Packing& p) {
  AtlasReport& r = s.r;
  for (const Group& g : p.groups)
    if (g.charts.size() > 1) {
      ++r.sharedBlocks, r.blockedCharts += g.charts.size();
      for (uint32_t i : g.charts)
        for (uint32_t f : s.charts[i].faces) r.blockedSurface += s.mesh.faceArea[f] / s.meshArea;
    }
  r.charts = s.charts.size();
  for (const Chart& c : s.charts) r.lscmCharts += c.lscm;
  r.texelsPerMetre = p.density;
}

// Emission of the atlas mesh: each chart's vertices duplicated with their stored uvs (a vertex on
// a seam belongs to every chart it borders), faces renumbered in place; the report gets the
// packing efficiency, the stretch percentiles, the time and the overlap count of the result.
TriangleMesh emitAtlasMesh(AtlasState& s, const std::vector<std::vector<Vec2>>& chartUv, double density,
                           const Timer& timer) {
  const TriangleMesh& mesh = s.mesh;
  const std::vector<Chart>& charts = s.charts;
  AtlasReport& r = s.r;
  TriangleMesh out = mesh;
  out.positions.clear();
  out.normals.clear();
  out.uvs.clear();
  const double R = s.o.gutterResolution;
  std::vector<double> stretch;
  double uvArea = 0;
  for (size_t i = 0; i < charts.size(); ++i) {
    const Chart& c = charts[i];
    const int base = static_cast<int>(out.positions.size());
    for (size_t v = 0; v < c.vertices.size(); ++v) {
      out.positions.push_back(mesh.positions[c.vertices[v]]);
      if (!mesh.normals.empty()) out.normals.push_back(mesh.normals[c.vertices[v]]);
      out.uvs.push_back(chartUv[i][v]);
    }
    for (uint32_t f : c.faces) {
      for (int k = 0; k < 3; ++k) out.triangles[f][k] = base + c.local.at(mesh.triangles[f][k]);
      const auto& t = out.triangles[f];
      const double a = 0.5 * std::abs(cross2(out.uvs[t[0]].cast<double>(), out.uvs[t[1]].cast<double>(),
                                             out.uvs[t[2]].cast<double>()));
      uvArea += a;
      stretch.push_back(std::sqrt(a * R * R / (density * density) / std::max<double>(mesh.faceArea[f], 1e-30)));
    }
  }
  r.packingEfficiency = uvArea;
  std::sort(stretch.begin(), stretch.end());
  if (!stretch.empty()) {
    r.stretchP05 = stretch[stretch.size() / 20];
    r.stretchMedian = stretch[stretch.size() / 2];
    r.stretchP95 = stretch[stretch.size() * 19 / 20];
  }
  r.seconds = timer.seconds();
  r.uvOverlaps = countUvOverlaps(out, SIZE_MAX);
  return out;
}

}  // namespace atlas_detail

size_t countUvOverlaps(const TriangleMesh& mesh, size_t stopAfter) {
  std::vector<uint32_t> faces(mesh.triangles.size());
  std::iota(faces.begin(), faces.end(), 0);
  return countOverlaps(
      faces, [&](uint32_t f, int k) { return Vec2d(mesh.uvs[mesh.triangles[f][k]].cast<double>()); }, stopAfter);
}

bool hasValidUvAtlas(const TriangleMesh& mesh) {
  if (!mesh.hasUv()) return false;
  for (const Vec2& uv : mesh.uvs)
    if (!(uv.minCoeff() >= 0.0f && uv.maxCoeff() <= 1.0f)) return false;
  for (size_t f = 0; f < mesh.triangles.size(); ++f) {
    const auto& t = mesh.triangles[f];
    if (std::abs(cross2(mesh.uvs[t[0]].cast<double>(), mesh.uvs[t[1]].cast<double>(), mesh.uvs[t[2]].cast<double>())) <=
        0)
      return false;
  }
  return countUvOverlaps(mesh, 1) == 0;
}

std::string AtlasReport::summary() const {
  if (keptInputUv) return "kept the mesh's own uv atlas (valid, no overlaps)";
  return fmt::format(
      "{} charts ({} least-squares conformal, {} split for overlaps, {} small ones merged, {} hollow ones cut, {} tiny "
      "ones in {} shared blocks holding {:.1f}% of the surface), packing efficiency {:.3f}, {:.1f} texels/m, "
      "stretch p05/median/p95 {:.3f}/{:.3f}/{:.3f}, {} uv overlaps, {:.1f}s",
      charts, lscmCharts, splitCharts, mergedCharts, hollowCharts, blockedCharts, sharedBlocks, 100 * blockedSurface,
      packingEfficiency, texelsPerMetre, stretchP05, stretchMedian, stretchP95, uvOverlaps, seconds);
}

TriangleMesh buildAtlas(const TriangleMesh& mesh, const AtlasOptions& o, AtlasReport* report) {
  AtlasReport local;
  AtlasReport& r = report ? *report : local;
  r = AtlasReport{};
  Timer timer;
  if (o.keepValidUv && hasValidUvAtlas(mesh)) {
    r.keptInputUv = true;
    return mesh;
  }
  AtlasState s = analyseMesh(mesh, o, r);
  chartMesh(s);
  spdlog::debug("atlas: {} charts grown and mapped at {:.1f}s", s.charts.size(), timer.seconds());
  mergeSmallCharts(s);
  cutHollowCharts(s);
  isolateSlivers(s);
  spdlog::debug("atlas: {} charts after merging and cutting at {:.1f}s", s.charts.size(), timer.seconds());
  // Disjoint footprints grown by r texels leave 2r >= gutterTexels empty texels between two charts.
  const int ring = (o.gutterTexels + 1) / 2;
  Packing p;
  std::vector<std::vector<Vec2>> chartUv;  // per chart and local vertex: the atlas uv as stored (float)
  for (;;) {                               // until no chart folds in float
    sortByFirstFace(s.charts);
    p.groups = groupCharts(s, ring);
    packGroups(s, ring, p);
    const std::vector<char> folded = storeUvs(s, ring, p, chartUv);
    spdlog::debug("atlas: {} groups packed at {:.1f} texels/m at {:.1f}s, {} charts fold in float", p.groups.size(),
                  p.density, timer.seconds(), std::count(folded.begin(), folded.end(), 1));
    if (std::find(folded.begin(), folded.end(), 1) == folded.end()) break;
    rechartFolded(s, folded);
  }
  reportCharts(s, p);
  return emitAtlasMesh(s, chartUv, p.density, timer);
}

}  // namespace relume
