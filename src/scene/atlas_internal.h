// Internals of the uv atlas (atlas.cpp), split by stage: charts and their maps (atlas.cpp), chart
// growth and the charting phases on the welded mesh (atlas_charts.cpp), footprint packing and the
// packing phases (atlas_pack.cpp). Not a public interface.
#pragma once
#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/system.h"
#include "scene/atlas.h"
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
std::vector<std::vector<uint32_t>> growCharts(const TriangleMesh& m, const std::vector<Vec3>& normals,
                                              const Topology& topo, const std::vector<uint32_t>& region,
                                              float coneDegrees, std::vector<int32_t>& state);

// A chart's footprint on the packing grid at one density: the texels its triangles touch, grown
// by `ring` texels (half the gutter, rounded up), as a bitmap with, per
// column, the first and one-past-last occupied row. Local texel coordinates of a chart point are
// shiftOf(ring) + uv * density, so the footprint is exactly what the texel map will rasterise there.
struct Footprint {
  int w = 0, h = 0;
  std::vector<uint8_t> bits;     // h rows of w
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

// Twice the signed area of a 2D triangle.
inline double cross2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

// A connected set of faces mapped to the plane without flips or overlaps, in metres.
struct Chart {
  std::vector<uint32_t> faces;
  std::vector<int> vertices;           // original vertex ids
  std::unordered_map<int, int> local;  // original vertex -> index in vertices
  std::vector<Eigen::Vector2d> uv;     // per local vertex, metres
  bool lscm = false;
  float cone = 0;  // the normal cone it was grown with
};

// Maps a chart (atlas.cpp): false when it has no map without flips or overlaps.
bool parameterise(const TriangleMesh& m, const std::vector<Vec3>& normals, float cosPlanar, Chart& c);
// Turns a mapped chart to its minimum-area box at the origin, wider than tall.
void orientChart(Chart& c);
// The chart of some of `parent`'s faces, keeping the parent's map.
Chart subChart(const TriangleMesh& m, const Chart& parent, std::vector<uint32_t> faces);
// A hollow (frame-like) chart cut into straight parts; empty when it is not hollow.
std::vector<Chart> splitHollow(const TriangleMesh& m, const Topology& topo, const Chart& c, double density);
// Whether a chart's stored (float) uvs fold: flip a face or overlap (never for a single face).
bool foldsInFloat(const TriangleMesh& m, const Chart& c, const std::vector<Vec2>& uv);

// Offset of a chart's footprint inside its footprint box, in texels.
double shiftOf(int ring);

// What the phases of buildAtlas pass along: the input, its per-face normals and adjacency, the
// report being filled, and the charts so far.
struct AtlasState {
  AtlasState(const TriangleMesh& mesh, const AtlasOptions& o, AtlasReport& r) : mesh(mesh), o(o), r(r) {}
  const TriangleMesh& mesh;
  const AtlasOptions& o;
  AtlasReport& r;
  std::vector<Vec3> normals;  // per face
  Topology topo;
  std::vector<int32_t> state;  // growCharts' scratch: -2 for every face between calls
  float cosPlanar = 0;         // charts flatter than o.planarDegrees are projected
  double meshArea = 0;         // square metres
  double maxDensity = 0;       // texels per metre at which the atlas is full: every texel covered
  std::vector<Chart> charts;
};

// The packing of the charts: groups (a chart, or a shared block of tiny ones), their footprints
// and placements at `density`, and each chart's group and offset in it.
struct Packing {
  std::vector<Group> groups;
  std::vector<std::array<Footprint, 4>> fps;  // per group
  std::vector<Placement> placement;           // per group
  std::vector<size_t> groupOf;                // per chart
  std::vector<Eigen::Vector2d> offsetOf;      // per chart
  double density = 0, lastMiss = 0;           // texels per metre at the gutter resolution
};

// Phases of buildAtlas, in order (atlas_charts.cpp, then atlas_pack.cpp, then atlas.cpp).
AtlasState analyseMesh(const TriangleMesh& mesh, const AtlasOptions& o, AtlasReport& r);
void chartRegion(AtlasState& s, std::vector<uint32_t> faces, float startCone);
void chartMesh(AtlasState& s);
void mergeSmallCharts(AtlasState& s);
void cutHollowCharts(AtlasState& s);
void isolateSlivers(AtlasState& s);
void sortByFirstFace(std::vector<Chart>& charts);
std::vector<Group> groupCharts(const AtlasState& s, int ring);
void packGroups(const AtlasState& s, int ring, Packing& p);
std::vector<char> storeUvs(const AtlasState& s, int ring, const Packing& p, std::vector<std::vector<Vec2>>& chartUv);
void rechartFolded(AtlasState& s, const std::vector<char>& folded);
void reportCharts(AtlasState& s, const Packing& p);
TriangleMesh emitAtlasMesh(AtlasState& s, const std::vector<std::vector<Vec2>>& chartUv, double density,
                           const Timer& timer);

}  // namespace relume::atlas_detail
