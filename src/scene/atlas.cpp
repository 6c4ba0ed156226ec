#include "scene/atlas.h"

#include <Eigen/SparseCholesky>
#include <fmt/format.h>

#include <map>
#include <numeric>
#include <queue>
#include <unordered_map>

#include "core/error.h"
#include "core/system.h"

namespace relume {
namespace {

using Vec2d = Eigen::Vector2d;

// Twice the signed area of a 2D triangle.
double cross2(const Vec2d& a, const Vec2d& b, const Vec2d& c) {
  return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

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

struct Chart {
  std::vector<uint32_t> faces;
  std::vector<int> vertices;                 // original vertex ids
  std::unordered_map<int, int> local;        // original vertex -> index in vertices
  std::vector<Vec2d> uv;                     // per local vertex, metres
  bool lscm = false;
};

void collectVertices(const TriangleMesh& m, Chart& c) {
  c.vertices.clear();
  c.local.clear();
  for (uint32_t f : c.faces)
    for (int k = 0; k < 3; ++k)
      if (c.local.emplace(m.triangles[f][k], static_cast<int>(c.vertices.size())).second) c.vertices.push_back(m.triangles[f][k]);
}

void planarProjection(const TriangleMesh& m, Chart& c, const Vec3& axis) {
  const ShadingFrame frame(axis.normalized());
  c.uv.resize(c.vertices.size());
  for (size_t i = 0; i < c.vertices.size(); ++i) {
    const Vec3& p = m.positions[c.vertices[i]];
    c.uv[i] = Vec2d(p.dot(frame.s), p.dot(frame.t));
  }
}

// Least-squares conformal map (Levy et al. 2002) with the two farthest vertices pinned.
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
      if (float d = (m.positions[c.vertices[i]] - m.positions[c.vertices[pinA]]).squaredNorm(); d > best) best = d, pinB = i;
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
  if (positive == 0)
    for (Vec2d& p : c.uv) p.y() = -p.y();
  const double scale = std::sqrt(area / std::max(uvArea, 1e-300));
  for (Vec2d& p : c.uv) p *= scale;
  return true;
}

// Rotates the chart to its minimum-area bounding rectangle (rotating calipers on the hull), puts
// it at the origin, and makes it wider than tall.
void orientChart(Chart& c) {
  std::vector<Vec2d> pts = c.uv;
  std::sort(pts.begin(), pts.end(), [](const Vec2d& a, const Vec2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
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
    const double angle = hull.size() < 2 ? 0.0 : std::atan2(hull[(i + 1) % hull.size()].y() - hull[i].y(), hull[(i + 1) % hull.size()].x() - hull[i].x());
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

struct Placement {
  int x = 0, y = 0;
};

// Skyline bottom-left packing of w x h rectangles (texels) into size x size; false if they do not fit.
bool skylinePack(const std::vector<std::pair<int, int>>& sizes, int size, std::vector<Placement>& out) {
  std::vector<size_t> order(sizes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return sizes[a].second != sizes[b].second ? sizes[a].second > sizes[b].second : sizes[a].first > sizes[b].first;
  });
  struct Segment { int x, y, w; };
  std::vector<Segment> sky{{0, 0, size}};
  out.assign(sizes.size(), {});
  for (size_t idx : order) {
    const auto [w, h] = sizes[idx];
    int bestY = INT32_MAX, bestX = 0, bestWaste = INT32_MAX;
    size_t bestI = 0;
    for (size_t i = 0; i < sky.size(); ++i) {
      if (sky[i].x + w > size) break;
      int y = 0, covered = 0, waste = 0;
      for (size_t j = i; j < sky.size() && covered < w; ++j) {
        y = std::max(y, sky[j].y);
        covered += sky[j].w;
      }
      if (covered < w || y + h > size) continue;
      covered = 0;
      for (size_t j = i; j < sky.size() && covered < w; ++j) {
        const int span = std::min(sky[j].w, w - covered);
        waste += span * (y - sky[j].y);
        covered += span;
      }
      if (y < bestY || (y == bestY && waste < bestWaste)) bestY = y, bestX = sky[i].x, bestWaste = waste, bestI = i;
    }
    if (bestY == INT32_MAX) return false;
    out[idx] = {bestX, bestY};
    // Replace the covered span of the skyline by the new top.
    std::vector<Segment> next(sky.begin(), sky.begin() + static_cast<long>(bestI));
    next.push_back({bestX, bestY + h, w});
    int end = bestX + w;
    for (size_t j = bestI; j < sky.size(); ++j) {
      const int segEnd = sky[j].x + sky[j].w;
      if (segEnd <= end) continue;
      const int start = std::max(sky[j].x, end);
      next.push_back({start, sky[j].y, segEnd - start});
    }
    sky.clear();
    for (const Segment& s : next)
      if (!sky.empty() && sky.back().y == s.y) sky.back().w += s.w;
      else sky.push_back(s);
  }
  return true;
}

std::vector<std::vector<uint32_t>> faceAdjacency(const TriangleMesh& m) {
  std::vector<std::pair<uint64_t, uint32_t>> edges;
  edges.reserve(m.triangles.size() * 3);
  for (uint32_t f = 0; f < m.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      const uint64_t a = static_cast<uint32_t>(m.triangles[f][k]), b = static_cast<uint32_t>(m.triangles[f][(k + 1) % 3]);
      edges.push_back({std::min(a, b) << 32 | std::max(a, b), f});
    }
  std::sort(edges.begin(), edges.end());
  std::vector<std::vector<uint32_t>> adj(m.triangles.size());
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j].first == edges[i].first) ++j;
    for (size_t a = i; a < j; ++a)
      for (size_t b = i; b < j; ++b)
        if (a != b) adj[edges[a].second].push_back(edges[b].second);
    i = j;
  }
  return adj;
}

// Region growing by normal cone around each seed's normal, within one object and one region.
std::vector<std::vector<uint32_t>> growCharts(const TriangleMesh& m, const std::vector<Vec3>& normals,
                                              const std::vector<std::vector<uint32_t>>& adj,
                                              const std::vector<uint32_t>& region, float coneDegrees) {
  const float cosCone = std::cos(coneDegrees * kPi / 180.0f);
  std::unordered_map<uint32_t, int> inRegion;
  for (uint32_t f : region) inRegion[f] = -1;
  std::vector<std::vector<uint32_t>> charts;
  for (uint32_t seed : region) {
    if (inRegion[seed] >= 0) continue;
    const int id = static_cast<int>(charts.size());
    charts.emplace_back();
    std::queue<uint32_t> q;
    q.push(seed);
    inRegion[seed] = id;
    while (!q.empty()) {
      const uint32_t f = q.front();
      q.pop();
      charts[id].push_back(f);
      for (uint32_t g : adj[f]) {
        auto it = inRegion.find(g);
        if (it == inRegion.end() || it->second >= 0 || m.faceObject[g] != m.faceObject[seed]) continue;
        if (normals[g].dot(normals[seed]) < cosCone) continue;
        it->second = id;
        q.push(g);
      }
    }
  }
  return charts;
}

}  // namespace

size_t countUvOverlaps(const TriangleMesh& mesh, size_t stopAfter) {
  std::vector<uint32_t> faces(mesh.triangles.size());
  std::iota(faces.begin(), faces.end(), 0);
  return countOverlaps(faces, [&](uint32_t f, int k) { return Vec2d(mesh.uvs[mesh.triangles[f][k]].cast<double>()); }, stopAfter);
}

bool hasValidUvAtlas(const TriangleMesh& mesh) {
  if (!mesh.hasUv()) return false;
  for (const Vec2& uv : mesh.uvs)
    if (!(uv.minCoeff() >= 0.0f && uv.maxCoeff() <= 1.0f)) return false;
  for (size_t f = 0; f < mesh.triangles.size(); ++f) {
    const auto& t = mesh.triangles[f];
    if (std::abs(cross2(mesh.uvs[t[0]].cast<double>(), mesh.uvs[t[1]].cast<double>(), mesh.uvs[t[2]].cast<double>())) <= 0) return false;
  }
  return countUvOverlaps(mesh, 1) == 0;
}

std::string AtlasReport::summary() const {
  if (keptInputUv) return "kept the mesh's own uv atlas (valid, no overlaps)";
  return fmt::format("{} charts ({} least-squares conformal, {} split for overlaps), packing efficiency {:.3f}, {:.1f} texels/m, "
                     "stretch p05/median/p95 {:.3f}/{:.3f}/{:.3f}, {:.1f}s",
                     charts, lscmCharts, splitCharts, packingEfficiency, texelsPerMetre, stretchP05, stretchMedian, stretchP95, seconds);
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
  std::vector<Vec3> normals(mesh.triangles.size());
  for (size_t f = 0; f < normals.size(); ++f) normals[f] = mesh.faceNormal(f);
  const auto adj = faceAdjacency(mesh);

  // Chart, parameterise, and split any chart whose map overlaps itself with a narrower cone.
  std::vector<Chart> charts;
  std::vector<std::pair<std::vector<uint32_t>, float>> work;
  std::vector<uint32_t> all(mesh.triangles.size());
  std::iota(all.begin(), all.end(), 0);
  work.push_back({all, o.coneDegrees});
  const float cosPlanar = std::cos(o.planarDegrees * kPi / 180.0f);
  while (!work.empty()) {
    auto [region, cone] = std::move(work.back());
    work.pop_back();
    for (auto& faces : growCharts(mesh, normals, adj, region, cone)) {
      Chart c;
      c.faces = std::move(faces);
      collectVertices(mesh, c);
      Vec3 axis = Vec3::Zero();
      for (uint32_t f : c.faces) axis += mesh.faceArea[f] * normals[f];
      axis.normalize();
      // Near-planar by area: noisy scans have a few steep faces on flat walls, which a planar
      // projection handles with less distortion than a conformal map with two pins.
      double area = 0, alignedArea = 0;
      for (uint32_t f : c.faces) area += mesh.faceArea[f], alignedArea += mesh.faceArea[f] * normals[f].dot(axis);
      const bool planar = alignedArea >= cosPlanar * area;
      if (planar || !lscm(mesh, c)) {
        // Every face is within the cone of the seed normal, so projecting along it never flips.
        planarProjection(mesh, c, planar ? axis : normals[c.faces.front()]);
      } else {
        c.lscm = true;
      }
      const bool overlaps = c.faces.size() > 1 &&
          countOverlaps(c.faces, [&](uint32_t f, int k) { return c.uv[c.local.at(mesh.triangles[f][k])]; }, 1) > 0;
      if (overlaps) {
        ++r.splitCharts;
        work.push_back({std::move(c.faces), cone * 0.5f});
        continue;
      }
      r.lscmCharts += c.lscm;
      orientChart(c);
      charts.push_back(std::move(c));
    }
  }
  // Deterministic order whatever the work-queue order was: by first face.
  std::sort(charts.begin(), charts.end(), [](const Chart& a, const Chart& b) { return a.faces.front() < b.faces.front(); });
  r.charts = charts.size();

  // Largest density (texels per metre at the gutter resolution) at which everything packs.
  const int pad = (o.gutterTexels + 1) / 2;  // per side: at least `gutterTexels` between charts
  std::vector<Eigen::AlignedBox2d> extent(charts.size());
  for (size_t i = 0; i < charts.size(); ++i)
    for (const Vec2d& p : charts[i].uv) extent[i].extend(p);
  std::vector<Placement> placement;
  auto sizesAt = [&](double density) {
    std::vector<std::pair<int, int>> s(charts.size());
    for (size_t i = 0; i < charts.size(); ++i)
      s[i] = {static_cast<int>(std::ceil(extent[i].sizes().x() * density)) + 1 + 2 * pad,
              static_cast<int>(std::ceil(extent[i].sizes().y() * density)) + 1 + 2 * pad};
    return s;
  };
  double totalArea = 0;
  for (float a : mesh.faceArea) totalArea += a;
  double lo = 0, hi = std::sqrt(static_cast<double>(o.gutterResolution) * o.gutterResolution / std::max(totalArea, 1e-12)) * 1.01;
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    (skylinePack(sizesAt(mid), o.gutterResolution, placement) ? lo : hi) = mid;
  }
  if (!(lo > 0) || !skylinePack(sizesAt(lo), o.gutterResolution, placement))
    fail("uv atlas: {} charts do not fit a {}^2 atlas with {}-texel gutters", charts.size(), o.gutterResolution, o.gutterTexels);
  r.texelsPerMetre = lo;

  TriangleMesh out = mesh;
  out.positions.clear();
  out.normals.clear();
  out.uvs.clear();
  const double R = o.gutterResolution;
  std::vector<double> stretch;
  double uvArea = 0;
  for (size_t i = 0; i < charts.size(); ++i) {
    const Chart& c = charts[i];
    const int base = static_cast<int>(out.positions.size());
    for (size_t v = 0; v < c.vertices.size(); ++v) {
      out.positions.push_back(mesh.positions[c.vertices[v]]);
      if (!mesh.normals.empty()) out.normals.push_back(mesh.normals[c.vertices[v]]);
      const Vec2d uv = (Vec2d(placement[i].x + pad + 0.5, placement[i].y + pad + 0.5) + c.uv[v] * lo) / R;
      out.uvs.push_back(uv.cast<float>());
    }
    for (uint32_t f : c.faces) {
      for (int k = 0; k < 3; ++k) out.triangles[f][k] = base + c.local.at(mesh.triangles[f][k]);
      const auto& t = out.triangles[f];
      const double a = 0.5 * std::abs(cross2(out.uvs[t[0]].cast<double>(), out.uvs[t[1]].cast<double>(), out.uvs[t[2]].cast<double>()));
      uvArea += a;
      stretch.push_back(std::sqrt(a * R * R / (lo * lo) / std::max<double>(mesh.faceArea[f], 1e-30)));
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
  return out;
}

}  // namespace relume
