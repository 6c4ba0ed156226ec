#include <algorithm>
#include <numeric>
#include <queue>

#include "scene/atlas_internal.h"

namespace relume::atlas_detail {

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
  std::sort(edges.begin(), edges.end(), [](const HalfEdge& a, const HalfEdge& b) { return a.key != b.key ? a.key < b.key : a.face < b.face; });
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

std::vector<std::vector<uint32_t>> growCharts(const TriangleMesh& m, const std::vector<Vec3>& normals, const Topology& topo,
                                              const std::vector<uint32_t>& region, float coneDegrees, std::vector<int32_t>& state) {
  const float cosCone = std::cos(coneDegrees * kPi / 180.0f);
  constexpr float kBoundaryWeight = 0.5f;
  std::vector<uint32_t> seeds = region;
  std::sort(seeds.begin(), seeds.end(), [&](uint32_t a, uint32_t b) { return m.faceArea[a] != m.faceArea[b] ? m.faceArea[a] > m.faceArea[b] : a < b; });
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

}  // namespace relume::atlas_detail
