#include <algorithm>
#include <climits>
#include <cmath>
#include <map>
#include <numeric>

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

std::vector<Group> shareBlocks(const std::vector<Vec2d>& size, const std::vector<int32_t>& object, const std::vector<char>& tiny,
                               double margin, double maxBlockArea) {
  std::vector<Group> groups;
  std::map<int32_t, std::vector<uint32_t>> tinyOf;  // ordered: deterministic block order
  for (uint32_t i = 0; i < size.size(); ++i)
    if (tiny[i]) tinyOf[object[i]].push_back(i);
    else groups.push_back({{i}, {Vec2d::Zero()}});
  auto cell = [&](uint32_t i) { return (size[i].x() + margin) * (size[i].y() + margin); };
  for (auto& [obj, members] : tinyOf) {
    std::stable_sort(members.begin(), members.end(), [&](uint32_t a, uint32_t b) { return size[a].y() > size[b].y(); });
    // Blocks of consecutive members (similar heights), each shelf-packed into a near-square.
    for (size_t first = 0; first < members.size();) {
      size_t last = first;
      double area = 0;
      while (last < members.size() && (last == first || area + cell(members[last]) <= maxBlockArea)) area += cell(members[last++]);
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

}  // namespace relume::atlas_detail
