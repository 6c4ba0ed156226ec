// Internals of the uv atlas (atlas.cpp), split by stage: chart growth on the welded mesh
// (atlas_charts.cpp) and footprint packing (atlas_pack.cpp). Not a public interface.
#pragma once
#include <array>
#include <cstdint>
#include <vector>

#include "scene/mesh.h"

namespace relume::atlas_detail {

// Face adjacency on the welded mesh: vertices at the same position are one vertex (real meshes
// split vertices at every normal or uv seam), and two faces are neighbours across an edge only when
// exactly two faces of one object share it with opposite directions (manifold, consistently
// wound). Non-manifold edges, winding flips and object borders are chart borders.
struct Topology {
  std::vector<std::array<int32_t, 3>> neighbour;  // across edge k = (corner k, corner k+1); -1: border
  std::vector<std::array<float, 3>> edgeLength;
};

Topology buildTopology(const TriangleMesh& m);

// Grows charts over `region` one at a time from the largest unassigned face (ties: lower index).
// Candidates are taken in order of a cost that weighs the normal's deviation from the chart's
// area-weighted mean normal and how much the face lengthens the chart's boundary (a face closing
// a notch costs less than one sticking out), so charts grow compact; a face joins while its normal
// stays within `coneDegrees` of the chart's mean normal. `state` holds -1 for the region's faces on
// entry (-2 elsewhere) and is restored.
std::vector<std::vector<uint32_t>> growCharts(const TriangleMesh& m, const std::vector<Vec3>& normals, const Topology& topo,
                                              const std::vector<uint32_t>& region, float coneDegrees, std::vector<int32_t>& state);

// A chart's footprint on the packing grid at one density: the texels its triangles touch, grown
// by `ring` texels (half the gutter, rounded up), as a bitmap with, per
// column, the first and one-past-last occupied row. Local texel coordinates of a chart point are
// shiftOf(ring) + uv * density, so the footprint is exactly what the texel map will rasterise there.
struct Footprint {
  int w = 0, h = 0;
  std::vector<uint8_t> bits;  // h rows of w
  std::vector<int> bottom, top;  // per column: first occupied row, one past the last (bottom = h if empty)
  bool at(int x, int y) const { return bits[static_cast<size_t>(y) * w + x] != 0; }
};

// The footprint turned by k quarter turns: texel (x, y) goes to (h-1-y, x) per turn.
Footprint rotated(const Footprint& in, int k);

// Local texel coordinates of a chart point after k quarter turns of a w x h footprint.
Eigen::Vector2d turn(Eigen::Vector2d q, int k, int w, int h);

struct Placement {
  int x = 0, y = 0, turns = 0;
};

// Profile packing: footprints (longest side first) drop onto a per-column height map of a
// `size`-wide strip, resting their bottom profile on it (so a chart nests into the steps left by
// the ones before it, not only on their bounding boxes: two single-triangle charts, common where
// T-junctions cut a flat wall into unconnected faces, fill one rectangle), at the column and
// quarter turn with the least (top x width + area left empty under the chart). Returns the strip
// height used.
int profilePack(const std::vector<std::array<Footprint, 4>>& fps, int size, std::vector<Placement>& out);

// Charts packed as one footprint: a chart on its own, or a shared block of tiny charts of one
// object, each at its offset (metres) inside the block.
struct Group {
  std::vector<uint32_t> charts;
  std::vector<Eigen::Vector2d> offset;
};

// Every chart on its own, except the `tiny` ones: per object (in chart order, tallest first), they
// are shelf-packed side by side, `margin` metres apart, into near-square blocks of at most
// `maxBlockArea` square metres. A tiny chart alone pays a whole gutter ring on the packing grid
// (9 texels for a sub-texel chart); in a block they share one. `size` is each chart's uv box (from
// the origin, metres).
std::vector<Group> shareBlocks(const std::vector<Eigen::Vector2d>& size, const std::vector<int32_t>& object,
                               const std::vector<char>& tiny, double margin, double maxBlockArea);

}  // namespace relume::atlas_detail
