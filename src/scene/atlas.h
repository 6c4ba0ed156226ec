// UV atlas: keeps a mesh's own uvs when they are valid (inside [0,1], no two triangles
// overlapping), otherwise charts the mesh (per object, by normal cone and connectivity),
// parameterises each chart (planar projection when near-planar, least-squares conformal maps
// otherwise), scales every chart to one world-space texel density and packs them with a gutter
// (tiny charts of one object share blocks, one gutter around each block).
// Same mesh in, same atlas out.
#pragma once
#include <string>

#include "scene/mesh.h"

namespace relume {

struct AtlasOptions {
  // Charts are packed on this resolution's texel grid with at least `gutterTexels` empty texels
  // between them, so every finer power-of-two resolution keeps a gutter at least as wide and a
  // one-texel dilation ring per chart never collides with a neighbour at any stage.
  int gutterResolution = 1024;
  int gutterTexels = 2;
  float coneDegrees = 60.0f;    // faces join a chart while their normal is within this of the seed's
  float planarDegrees = 20.0f;  // charts whose area-weighted mean normal deviation is below this
                                // use planar projection, others least-squares conformal maps
  // Charts smaller than sharedBlockTexels, or narrower than sharedBlockWidth texels (at the density
  // where the atlas would be full), are packed side by side in shared blocks per object, one gutter
  // around each block: lookups near such a chart's border may read a texel of another tiny chart of
  // the same object.
  double sharedBlockTexels = 16;
  double sharedBlockWidth = 1;
  bool keepValidUv = true;
};

struct AtlasReport {
  bool keptInputUv = false;
  size_t charts = 0, lscmCharts = 0, splitCharts = 0, mergedCharts = 0;
  size_t hollowCharts = 0;                     // frame-like charts cut into straight parts
  size_t sharedBlocks = 0, blockedCharts = 0;  // shared blocks of tiny charts, and the charts in them
  double blockedSurface = 0;                   // the share of the mesh's area in shared blocks
  double packingEfficiency = 0;                // charted uv area / atlas area
  double texelsPerMetre = 0;                   // at AtlasOptions::gutterResolution
  // Stretch: sqrt(uv area / 3D area), normalised by the atlas density; 1 = no distortion.
  double stretchP05 = 0, stretchMedian = 0, stretchP95 = 0;
  size_t uvOverlaps = 0;  // pairs of triangles overlapping in the output (countUvOverlaps): 0
  double seconds = 0;     // charting and packing (the overlap count is not timed)
  std::string summary() const;
};

// Returns the mesh with a per-vertex uv atlas (vertices are split along chart seams).
TriangleMesh buildAtlas(const TriangleMesh& mesh, const AtlasOptions& options, AtlasReport* report = nullptr);

// Exact test: pairs of triangles whose uv interiors overlap (touching edges/corners do not count).
size_t countUvOverlaps(const TriangleMesh& mesh, size_t stopAfter = 1);
// True if every uv is inside [0,1] and no two triangles overlap.
bool hasValidUvAtlas(const TriangleMesh& mesh);

}  // namespace relume
