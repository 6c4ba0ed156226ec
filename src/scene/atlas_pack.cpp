#include <algorithm>
#include <climits>
#include <cmath>
#include <map>
#include <numeric>

#include <tbb/parallel_for.h>

#include "core/error.h"
#include "scene/atlas_internal.h"

namespace relume::atlas_detail {

using Vec2d = Eigen::Vector2d;

Footprint rotated(const Footprint& in, int k) {
  if (in.bits.empty()) return in;  // the stand-in for a chart too large to fit
  Footprint fp = in;
  for (int t = 0; t < k; ++t) {
    Footprint r;
    r.w = fp.h, r.h = fp.w;
    r.bits.assign(fp.bits.size(), 0);
    for (int y = 0; y < fp.h; ++y)
      for (int x = 0; x < fp.w; ++x) r.bits[static_cast<size_t>(x) * r.w + (fp.h - 1 - y)] = fp.at(x, y);
    fp = std::move(r);
  }
  fp.bottom.assign(fp.w, fp.h);
  fp.top.assign(fp.w, 0);
  for (int y = 0; y < fp.h; ++y)
    for (int x = 0; x < fp.w; ++x)
      if (fp.at(x, y)) fp.bottom[x] = std::min(fp.bottom[x], y), fp.top[x] = y + 1;
  return fp;
}

Vec2d turn(Vec2d q, int k, int w, int h) {
  for (int t = 0; t < k; ++t) {
    q = Vec2d(h - q.y(), q.x());
    std::swap(w, h);
  }
  return q;
}

int profilePack(const std::vector<std::array<Footprint, 4>>& fps, int size, std::vector<Placement>& out) {
  std::vector<size_t> order(fps.size());
  std::iota(order.begin(), order.end(), 0);
  auto key = [&](size_t i) { return std::max(fps[i][0].w, fps[i][0].h); };
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return key(a) > key(b); });
  std::vector<int> height(size, 0);
  out.assign(fps.size(), {});
  int used = 0;
  struct Best {
    long score = LONG_MAX;
    Placement at{-1, 0, 0};
    bool operator<(const Best& o) const {  // ties: the first found (fewer turns, then leftmost)
      return score != o.score ? score < o.score : at.turns != o.at.turns ? at.turns < o.at.turns : at.x < o.at.x;
    }
  };
  for (size_t i : order) {
    Best best;
    for (int k = 0; k < 4; ++k) {
      const Footprint& fp = fps[i][k];
      const int lastTop = *std::max_element(fp.top.begin(), fp.top.end());
      for (int x = 0; x + fp.w <= size; ++x) {
        int y = 0;
        for (int c = 0; c < fp.w; ++c)
          if (fp.top[c] > 0) y = std::max(y, height[x + c] - fp.bottom[c]);
        long gap = 0;
        for (int c = 0; c < fp.w; ++c)
          if (fp.top[c] > 0) gap += y + fp.bottom[c] - height[x + c];
        const Best here{static_cast<long>(y + lastTop) * fp.w + gap, {x, y, k}};
        if (here < best) best = here;
      }
    }
    if (best.at.x < 0) return INT32_MAX;  // wider than the strip
    const Footprint& fp = fps[i][best.at.turns];
    for (int c = 0; c < fp.w; ++c)
      if (fp.top[c] > 0) height[best.at.x + c] = best.at.y + fp.top[c];
    used = std::max(used, best.at.y + *std::max_element(fp.top.begin(), fp.top.end()));
    out[i] = best.at;
    if (used > size) return used;  // does not fit: the caller only needs to know that
  }
  return used;
}

std::vector<Group> shareBlocks(const std::vector<Vec2d>& size, const std::vector<int32_t>& object,
                               const std::vector<char>& tiny, double margin, double maxBlockArea) {
  std::vector<Group> groups;
  std::map<int32_t, std::vector<uint32_t>> tinyOf;  // ordered: deterministic block order
  for (uint32_t i = 0; i < size.size(); ++i)
    if (tiny[i])
      tinyOf[object[i]].push_back(i);
    else
      groups.push_back({{i}, {Vec2d::Zero()}});
  auto cell = [&](uint32_t i) { return (size[i].x() + margin) * (size[i].y() + margin); };
  for (auto& [obj, members] : tinyOf) {
    std::stable_sort(members.begin(), members.end(), [&](uint32_t a, uint32_t b) { return size[a].y() > size[b].y(); });
    // Blocks of consecutive members (similar heights), each shelf-packed into a near-square.
    for (size_t first = 0; first < members.size();) {
      size_t last = first;
      double area = 0;
      while (last < members.size() && (last == first || area + cell(members[last]) <= maxBlockArea))
        area += cell(members[last++]);
      double width = std::sqrt(area);
      for (size_t j = first; j < last; ++j) width = std::max(width, size[members[j]].x());
      Group& g = groups.emplace_back();
      double x = 0, y = 0, shelf = 0;
      for (size_t j = first; j < last; ++j) {
        const Vec2d s = size[members[j]];
        if (x > 0 && x + s.x() > width) x = 0, y += shelf + margin, shelf = 0;
        g.charts.push_back(members[j]);
        g.offset.emplace_back(x, y);
        x += s.x() + margin;
        shelf = std::max(shelf, s.y());
      }
      first = last;
    }
  }
  return groups;
}

double shiftOf(int ring) { return ring + 0.25; }  // the ring, then a quarter texel off the grid lines

namespace {

// The footprint of a group of charts (each at its offset) whose box is `box`. A group larger than
// `limit` texels gets a stand-in footprint wider than the strip (no bits).
Footprint footprintOf(const TriangleMesh& m, const std::vector<Chart>& charts, const Group& g,
                      const Eigen::AlignedBox2d& box, double density, int ring, int limit) {
  const double shift = shiftOf(ring);
  Footprint fp;
  if (!(std::max(box.sizes().x(), box.sizes().y()) * density < limit)) {  // cannot fit: say so without allocating it
    fp.w = fp.h = limit + 1;
    fp.bottom.assign(1, 0), fp.top.assign(1, 1);
    return fp;
  }
  fp.w = static_cast<int>(std::floor(shift + box.sizes().x() * density + 1e-3)) + 1 + ring;
  fp.h = static_cast<int>(std::floor(shift + box.sizes().y() * density + 1e-3)) + 1 + ring;
  std::vector<uint8_t> touched(static_cast<size_t>(fp.w) * fp.h, 0);
  auto touch = [&](const Vec2d(&v)[3]) {
    const double orient = cross2(v[0], v[1], v[2]) >= 0 ? 1.0 : -1.0;
    const int x0 = static_cast<int>(std::floor(std::min({v[0].x(), v[1].x(), v[2].x()}) - 1e-3));
    const int x1 = static_cast<int>(std::floor(std::max({v[0].x(), v[1].x(), v[2].x()}) + 1e-3));
    const int y0 = static_cast<int>(std::floor(std::min({v[0].y(), v[1].y(), v[2].y()}) - 1e-3));
    const int y1 = static_cast<int>(std::floor(std::max({v[0].y(), v[1].y(), v[2].y()}) + 1e-3));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        bool touches = true;  // separating axis with a 1e-3-texel margin: conservative for float uvs
        for (int e = 0; e < 3 && touches; ++e) {
          const Vec2d d = v[(e + 1) % 3] - v[e];
          const Vec2d inward = orient * Vec2d(-d.y(), d.x());
          const Vec2d corner(inward.x() >= 0 ? x + 1.0 : double(x), inward.y() >= 0 ? y + 1.0 : double(y));
          touches = inward.dot(corner - v[e]) >= -1e-3 * inward.norm();
        }
        if (touches) touched[static_cast<size_t>(y) * fp.w + x] = 1;
      }
  };
  for (size_t j = 0; j < g.charts.size(); ++j) {
    const Chart& c = charts[g.charts[j]];
    for (uint32_t f : c.faces) {
      Vec2d v[3];
      for (int k = 0; k < 3; ++k)
        v[k] = Vec2d(shift, shift) + (g.offset[j] + c.uv[c.local.at(m.triangles[f][k])]) * density;
      touch(v);
    }
  }
  fp.bits.assign(touched.size(), 0);
  for (int y = 0; y < fp.h; ++y)
    for (int x = 0; x < fp.w; ++x) {
      if (!touched[static_cast<size_t>(y) * fp.w + x]) continue;
      for (int dy = -ring; dy <= ring; ++dy)
        for (int dx = -ring; dx <= ring; ++dx) fp.bits[static_cast<size_t>(y + dy) * fp.w + x + dx] = 1;
    }
  return fp;
}

}  // namespace

// Grouping: charts under sharedBlockTexels or narrower than sharedBlockWidth at maxDensity share
// blocks per object, a tenth of a texel apart (at any density the packing ends at: far above float
// rounding), each block at most 1/64 of the atlas. Sharing costs lookup isolation, so only when it
// buys texture: when their own footprints would take over 1% of the atlas.
std::vector<Group> groupCharts(const AtlasState& s, int ring) {
  const TriangleMesh& mesh = s.mesh;
  const std::vector<Chart>& charts = s.charts;
  const AtlasOptions& o = s.o;
  const double maxDensity = s.maxDensity;
  const int G = o.gutterResolution;
  std::vector<Vec2d> size(charts.size());
  std::vector<int32_t> object(charts.size());
  std::vector<char> tiny(charts.size());
  double tinyFootprints = 0;  // texels at maxDensity
  for (size_t i = 0; i < charts.size(); ++i) {
    Eigen::AlignedBox2d box;
    double area = 0;
    for (const Vec2d& p : charts[i].uv) box.extend(p);
    for (uint32_t f : charts[i].faces) area += mesh.faceArea[f];
    size[i] = box.sizes();
    object[i] = mesh.faceObject[charts[i].faces.front()];
    tiny[i] =
        area * maxDensity * maxDensity < o.sharedBlockTexels || size[i].minCoeff() * maxDensity < o.sharedBlockWidth;
    if (tiny[i])
      tinyFootprints += (size[i].x() * maxDensity + 1 + 2 * ring) * (size[i].y() * maxDensity + 1 + 2 * ring);
  }
  if (tinyFootprints < 0.01 * G * G) std::fill(tiny.begin(), tiny.end(), 0);
  return shareBlocks(size, object, tiny, 0.1 / maxDensity, 1.0 / 64 * G * G / (maxDensity * maxDensity));
}

// Packing: the largest density (texels per metre at the gutter resolution) at which every group's
// footprint packs into the atlas, searched by secant-like steps while packings fit (a fitting pass
// reports its height), bisection once one has failed (a failing pass stops early, so its height
// says little), to 0.5%. A repack after re-charting the few charts that folded starts at the
// density found before and takes its miss as the bound: they add little, so that density mostly
// still fits and one pass settles it. Leaves the footprints and placements at that density.
void packGroups(const AtlasState& s, int ring, Packing& p) {
  const TriangleMesh& mesh = s.mesh;
  const std::vector<Chart>& charts = s.charts;
  const AtlasOptions& o = s.o;
  const double maxDensity = s.maxDensity;
  const int G = o.gutterResolution;
  const std::vector<Group>& groups = p.groups;
  std::vector<Eigen::AlignedBox2d> extent(groups.size());
  p.groupOf.assign(charts.size(), 0);
  p.offsetOf.assign(charts.size(), Vec2d::Zero());
  for (size_t g = 0; g < groups.size(); ++g)
    for (size_t j = 0; j < groups[g].charts.size(); ++j) {
      const size_t i = groups[g].charts[j];
      p.groupOf[i] = g, p.offsetOf[i] = groups[g].offset[j];
      for (const Vec2d& q : charts[i].uv) extent[g].extend(p.offsetOf[i] + q);
    }
  p.fps.assign(groups.size(), {});
  std::vector<Placement> trial;
  auto packAt = [&](double d) {
    tbb::parallel_for(size_t{0}, groups.size(), [&](size_t g) {
      const Footprint base = footprintOf(mesh, charts, groups[g], extent[g], d, ring, G);
      for (int k = 0; k < 4; ++k) p.fps[g][k] = rotated(base, k);
    });
    return profilePack(p.fps, G, trial);
  };
  const bool repack = p.density > 0;
  double fit = 0, miss = repack ? p.lastMiss : maxDensity;
  double d = repack ? p.density : miss * 0.9;
  for (int it = 0; it < 30 && miss > fit * 1.005; ++it) {
    const int used = packAt(d);
    if (used <= G) {
      fit = d, p.placement = trial;
      const double next = d * std::sqrt(static_cast<double>(G) / std::max(used, 1));
      d = next > d * 1.001 && next < miss ? next : 0.5 * (fit + miss);
    } else {
      miss = d;
      d = fit > 0 ? 0.5 * (fit + miss) : (repack ? 0.95 : 0.7) * miss;
    }
  }
  p.lastMiss = miss;
  if (!(fit > 0))
    fail("uv atlas: {} charts do not fit a {}^2 atlas with {}-texel gutters", charts.size(), G, o.gutterTexels);
  packAt(fit);  // footprints at the chosen density (the same placement as `placement`)
  p.density = fit;
}

// Storing: each chart's uvs as they will be stored, in float, at its placement. A chart of
// micro-triangles that maps without overlap in double can fold by a rounding: returns, per chart,
// whether it does (such charts are re-charted and everything repacked).
std::vector<char> storeUvs(const AtlasState& s, int ring, const Packing& p, std::vector<std::vector<Vec2>>& chartUv) {
  const std::vector<Chart>& charts = s.charts;
  const int G = s.o.gutterResolution;
  chartUv.assign(charts.size(), {});
  std::vector<char> bad(charts.size(), 0);
  tbb::parallel_for(size_t{0}, charts.size(), [&](size_t i) {
    const Chart& c = charts[i];
    const size_t g = p.groupOf[i];
    for (const Vec2d& q0 : c.uv) {
      const Vec2d q = turn(Vec2d::Constant(shiftOf(ring)) + (p.offsetOf[i] + q0) * p.density, p.placement[g].turns,
                           p.fps[g][0].w, p.fps[g][0].h);
      chartUv[i].push_back(((Vec2d(p.placement[g].x, p.placement[g].y) + q) / G).cast<float>());
    }
    bad[i] = foldsInFloat(s.mesh, c, chartUv[i]);
  });
  return bad;
}

}  // namespace relume::atlas_detail
