#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <queue>

#include "core/check.h"
#include "scene/atlas_internal.h"

namespace relume::atlas_detail {

using Vec2d = Eigen::Vector2d;

Topology buildTopology(const TriangleMesh& m) {
  const size_t nv = m.positions.size(), nf = m.triangles.size();
  std::vector<uint32_t> order(nv);
  std::iota(order.begin(), order.end(), 0u);
  auto less = [&](uint32_t a, uint32_t b) {
    const Vec3 &p = m.positions[a], &q = m.positions[b];
    return std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3);
  };
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return less(a, b) || (!less(b, a) && a < b); });
  std::vector<uint32_t> weld(nv);
  for (size_t i = 0, id = 0; i < nv; ++i) {
    if (i > 0 && less(order[i - 1], order[i])) ++id;
    weld[order[i]] = static_cast<uint32_t>(id);
  }
  struct HalfEdge {
    uint64_t key;
    uint32_t face;
    uint8_t corner, forward;
  };
  std::vector<HalfEdge> edges;
  edges.reserve(nf * 3);
  Topology t;
  t.neighbour.assign(nf, {-1, -1, -1});
  t.edgeLength.resize(nf);
  for (uint32_t f = 0; f < nf; ++f)
    for (int k = 0; k < 3; ++k) {
      const uint64_t a = weld[m.triangles[f][k]], b = weld[m.triangles[f][(k + 1) % 3]];
      edges.push_back({std::min(a, b) << 32 | std::max(a, b), f, static_cast<uint8_t>(k), static_cast<uint8_t>(a < b)});
      t.edgeLength[f][k] = (m.positions[m.triangles[f][(k + 1) % 3]] - m.positions[m.triangles[f][k]]).norm();
    }
  std::sort(edges.begin(), edges.end(),
            [](const HalfEdge& a, const HalfEdge& b) { return a.key != b.key ? a.key < b.key : a.face < b.face; });
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j].key == edges[i].key) ++j;
    if (j - i != 2) {
      i = j;
      continue;
    }
    const HalfEdge &a = edges[i], &b = edges[i + 1];
    if (a.face != b.face && a.forward != b.forward && m.faceObject[a.face] == m.faceObject[b.face]) {
      t.neighbour[a.face][a.corner] = static_cast<int32_t>(b.face);
      t.neighbour[b.face][b.corner] = static_cast<int32_t>(a.face);
    }
    i = j;
  }
  return t;
}

std::vector<std::vector<uint32_t>> growCharts(const TriangleMesh& m, const std::vector<Vec3>& normals,
                                              const Topology& topo, const std::vector<uint32_t>& region,
                                              float coneDegrees, std::vector<int32_t>& state) {
  const float cosCone = std::cos(coneDegrees * kPi / 180.0f);
  constexpr float kBoundaryWeight = 0.5f;
  std::vector<uint32_t> seeds = region;
  std::sort(seeds.begin(), seeds.end(), [&](uint32_t a, uint32_t b) {
    return m.faceArea[a] != m.faceArea[b] ? m.faceArea[a] > m.faceArea[b] : a < b;
  });
  for (uint32_t f : region) state[f] = -1;
  std::vector<std::vector<uint32_t>> charts;
  using Entry = std::pair<float, uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap;
  for (uint32_t seed : seeds) {
    if (state[seed] != -1) continue;
    const int32_t id = static_cast<int32_t>(charts.size());
    charts.emplace_back();
    Vec3 sum = Vec3::Zero();
    auto cost = [&](uint32_t f, const Vec3& mean) {
      float shared = 0, perimeter = 0;
      for (int k = 0; k < 3; ++k) {
        perimeter += topo.edgeLength[f][k];
        if (topo.neighbour[f][k] >= 0 && state[topo.neighbour[f][k]] == id) shared += topo.edgeLength[f][k];
      }
      return (1.0f - normals[f].dot(mean)) + kBoundaryWeight * (1.0f - 2.0f * shared / std::max(perimeter, 1e-30f));
    };
    auto add = [&](uint32_t f) {
      state[f] = id;
      charts[id].push_back(f);
      sum += m.faceArea[f] * normals[f];
      const Vec3 mean = sum.normalized();
      for (int k = 0; k < 3; ++k) {
        const int32_t g = topo.neighbour[f][k];
        if (g >= 0 && state[g] == -1) heap.push({cost(g, mean), static_cast<uint32_t>(g)});
      }
    };
    add(seed);
    while (!heap.empty()) {
      const auto [queued, f] = heap.top();
      heap.pop();
      if (state[f] != -1) continue;
      const Vec3 mean = sum.normalized();
      if (normals[f].dot(mean) < cosCone) continue;  // may come back through another neighbour
      if (const float now = cost(f, mean); now > queued + 1e-6f) {
        heap.push({now, f});  // the chart moved since this entry was queued
        continue;
      }
      add(f);
    }
  }
  for (uint32_t f : region) state[f] = -2;
  return charts;
}

// Mesh analysis: per-face normals and the welded adjacency every charting phase reads, and the
// largest density the atlas could have (every texel covered), which says what "small" and "tiny" are.
AtlasState analyseMesh(const TriangleMesh& mesh, const AtlasOptions& o, AtlasReport& r) {
  AtlasState s(mesh, o, r);
  s.normals.resize(mesh.triangles.size());
  for (size_t f = 0; f < s.normals.size(); ++f) s.normals[f] = mesh.faceNormal(f);
  s.topo = buildTopology(mesh);
  s.state.assign(mesh.triangles.size(), -2);
  s.cosPlanar = std::cos(o.planarDegrees * kPi / 180.0f);
  const int G = o.gutterResolution;
  for (float a : mesh.faceArea) s.meshArea += a;
  s.maxDensity = std::sqrt(static_cast<double>(G) * G / std::max(s.meshArea, 1e-12));  // every texel covered
  return s;
}

// Charting of a region: charts grown within `startCone` and mapped; a chart whose map overlaps
// itself (or has no valid map) is re-grown with half the cone. Below kMinConeDegrees its faces
// become one chart each, which always map (a single non-degenerate triangle), so this terminates
// on any input.
void chartRegion(AtlasState& s, std::vector<uint32_t> faces, float startCone) {
  constexpr float kMinConeDegrees = 1.0f;
  std::vector<std::pair<std::vector<uint32_t>, float>> work;
  work.push_back({std::move(faces), startCone});
  while (!work.empty()) {
    auto [region, cone] = std::move(work.back());
    work.pop_back();
    std::vector<std::vector<uint32_t>> grown;
    if (cone < kMinConeDegrees)
      for (uint32_t f : region) grown.push_back({f});
    else
      grown = growCharts(s.mesh, s.normals, s.topo, region, cone, s.state);
    for (auto& g : grown) {
      Chart c;
      c.faces = std::move(g);
      c.cone = cone;
      if (!parameterise(s.mesh, s.normals, s.cosPlanar, c)) {
        ++s.r.splitCharts;
        work.push_back({std::move(c.faces), cone * 0.5f});
        continue;
      }
      orientChart(c);
      s.charts.push_back(std::move(c));
    }
  }
}

// Charting of the whole mesh at the options' cone: the first set of mapped charts.
void chartMesh(AtlasState& s) {
  std::vector<uint32_t> all(s.mesh.triangles.size());
  std::iota(all.begin(), all.end(), 0);
  chartRegion(s, std::move(all), s.o.coneDegrees);
}

// Merging of small charts, which each pay a whole footprint: each chart under kSmallChartTexels at
// maxDensity, smallest first, joins the neighbour it shares the longest border with, when the
// union still maps (no flip or overlap, conformal stretch p95 <= kMaxStretch) and none of its faces
// is stretched below kMinMergedStretch. Targets above kMaxMergeTarget faces are left alone (each
// attempt re-maps the whole union).
void mergeSmallCharts(AtlasState& s) {
  const TriangleMesh& mesh = s.mesh;
  const Topology& topo = s.topo;
  std::vector<Chart>& charts = s.charts;
  const double maxDensity = s.maxDensity;
  constexpr double kSmallChartTexels = 16, kMinMergedStretch = 0.5;
  constexpr size_t kMaxMergeTarget = 500;
  std::sort(charts.begin(), charts.end(),
            [](const Chart& a, const Chart& b) { return a.faces.front() < b.faces.front(); });
  std::vector<int32_t> chartOf(mesh.triangles.size());
  std::vector<double> chartArea(charts.size(), 0);
  for (size_t i = 0; i < charts.size(); ++i)
    for (uint32_t f : charts[i].faces) chartOf[f] = static_cast<int32_t>(i), chartArea[i] += mesh.faceArea[f];
  std::vector<size_t> order;
  for (size_t i = 0; i < charts.size(); ++i)
    if (chartArea[i] * maxDensity * maxDensity < kSmallChartTexels) order.push_back(i);
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return chartArea[a] != chartArea[b] ? chartArea[a] < chartArea[b] : a < b; });
  for (size_t small : order) {
    if (charts[small].faces.empty() || chartArea[small] * maxDensity * maxDensity >= kSmallChartTexels) continue;
    std::map<int32_t, float> border;
    for (uint32_t f : charts[small].faces)
      for (int k = 0; k < 3; ++k)
        if (const int32_t g = topo.neighbour[f][k]; g >= 0 && chartOf[g] != static_cast<int32_t>(small))
          border[chartOf[g]] += topo.edgeLength[f][k];
    int32_t target = -1;
    float longest = 0;
    for (const auto& [c, length] : border)
      if (length > longest) longest = length, target = c;
    if (target < 0 || charts[target].faces.size() > kMaxMergeTarget) continue;
    Chart merged;
    merged.faces = charts[target].faces;
    merged.faces.insert(merged.faces.end(), charts[small].faces.begin(), charts[small].faces.end());
    merged.cone = charts[target].cone;
    if (!parameterise(mesh, s.normals, s.cosPlanar, merged)) continue;
    bool squashed = false;
    for (uint32_t f : merged.faces) {
      const auto& t = mesh.triangles[f];
      const double a = 0.5 * std::abs(cross2(merged.uv[merged.local.at(t[0])], merged.uv[merged.local.at(t[1])],
                                             merged.uv[merged.local.at(t[2])]));
      squashed = squashed || !(std::sqrt(a / mesh.faceArea[f]) >= kMinMergedStretch);
    }
    if (squashed) continue;
    orientChart(merged);
    for (uint32_t f : charts[small].faces) chartOf[f] = target;
    chartArea[target] += chartArea[small];
    charts[target] = std::move(merged);
    charts[small].faces.clear();
    ++s.r.mergedCharts;
  }
  std::erase_if(charts, [](const Chart& c) { return c.faces.empty(); });
}

// Cutting of hollow (frame-like) charts into straight parts (splitHollow), so the packer is not
// left with their empty insides; the parts go after the charts kept whole.
void cutHollowCharts(AtlasState& s) {
  std::vector<Chart>& charts = s.charts;
  std::vector<Chart> parts;
  for (Chart& c : charts)
    if (std::vector<Chart> split = splitHollow(s.mesh, s.topo, c, s.maxDensity); !split.empty()) {
      c.faces.clear();
      for (Chart& p : split) parts.push_back(std::move(p));
      ++s.r.hollowCharts;
    }
  for (Chart& p : parts) charts.push_back(std::move(p));
  std::erase_if(charts, [](const Chart& c) { return c.faces.empty(); });
}

// Isolation of slivers: faces narrower in uv than 1/1000 texel at the largest density possible
// (every texel covered), 16 float roundings at 1024^2, could fold when their uvs are stored as
// float, so they become charts of their own before packing.
void isolateSlivers(AtlasState& s) {
  const TriangleMesh& mesh = s.mesh;
  std::vector<Chart>& charts = s.charts;
  const double maxDensity = s.maxDensity;
  std::vector<Chart> singles;
  for (Chart& c : charts) {
    if (c.faces.size() == 1) continue;
    std::vector<uint32_t> keep;
    for (uint32_t f : c.faces) {
      Vec2d p[3];
      for (int k = 0; k < 3; ++k) p[k] = c.uv[c.local.at(mesh.triangles[f][k])];
      const double longest = std::max({(p[1] - p[0]).norm(), (p[2] - p[1]).norm(), (p[0] - p[2]).norm()});
      const double altitude = std::abs(cross2(p[0], p[1], p[2])) / std::max(longest, 1e-300);
      if (altitude * maxDensity < 1e-3)
        singles.emplace_back().faces = {f};
      else
        keep.push_back(f);
    }
    if (keep.size() == c.faces.size()) continue;
    c = keep.empty() ? Chart{} : subChart(mesh, c, std::move(keep));
  }
  for (Chart& c : singles) {
    [[maybe_unused]] const bool mapped = parameterise(mesh, s.normals, s.cosPlanar, c);
    DCHECK(mapped && "a single triangle projects on its own plane");
    orientChart(c);
    charts.push_back(std::move(c));
  }
  std::erase_if(charts, [](const Chart& c) { return c.faces.empty(); });
}

// Charts by first face: a deterministic order whatever the work-queue order was.
void sortByFirstFace(std::vector<Chart>& charts) {
  std::sort(charts.begin(), charts.end(),
            [](const Chart& a, const Chart& b) { return a.faces.front() < b.faces.front(); });
}

// Re-charting of the charts whose stored uvs fold: one chart per face (cone 0), which rounding
// cannot fold; the packing then starts again.
void rechartFolded(AtlasState& s, const std::vector<char>& folded) {
  std::vector<Chart> keep;
  std::vector<std::pair<std::vector<uint32_t>, float>> redo;
  for (size_t i = 0; i < s.charts.size(); ++i)
    if (folded[i])
      ++s.r.splitCharts, redo.push_back({std::move(s.charts[i].faces), 0.0f});
    else
      keep.push_back(std::move(s.charts[i]));
  s.charts = std::move(keep);
  for (auto& [faces, cone] : redo) chartRegion(s, std::move(faces), cone);
}

}  // namespace relume::atlas_detail
