// A segmentation for a mesh that comes without one (most scanners give none). The fit's per-object
// unknowns need it: one roughness and specular per object, and one light-source decision per object,
// so a lamp fused into the ceiling's mesh cannot be told from the ceiling unless it is its own
// object. Faces are grouped by
//   1. connectivity: faces that share no edge (after welding coincident vertices) never join;
//   2. creases: adjacent faces whose normals (smoothed over their neighbours, against mesh noise)
//      differ by more than `creaseDegrees` never join, nor do two regions of 16 faces or more
//      whose main normals differ by more than `regionCreaseDegrees` (a corner that noise rounded
//      into a ramp of small steps);
//   3. what the frames show (FaceAppearance): adjacent faces join, most similar first, unless their
//      observed radiance differs by more than `edgeContrast` and by more than its noise, or one is
//      seen clipped and the other not; two grown regions join only while their mean radiances stay
//      within `regionContrast` (so a ramp of mixed boundary faces cannot chain a lamp onto a wall).
//      Faces (regions) seen mostly clipped are not compared by radiance: their floors differ with
//      the exposures of the frames that saw them, not with the surface;
//   4. small regions (below `minAreaFraction` of the surface) merge into their most similar
//      neighbour, unless they are `keepBrighter` times brighter than it (and beyond their noise) or
//      clipped where it is not (a small lamp).
// The paper's supplement found such a naive segmentation about as good as the captured one.
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "scene/mesh.h"

namespace relume {

// What the frames show of one face.
struct FaceAppearance {
  Color logRadiance = Color::Zero();  // per channel, the log of the face's median observed radiance
  Color logError = Color::Zero();     // standard error of logRadiance (from the observations' spread)
  float clippedFraction = 0;          // of its observations, the share with a channel at the frame's clip
  bool observed = false;              // false: no frame saw it (it joins by geometry alone)
};

struct SegmentationOptions {
  float creaseDegrees = 40;
  float regionCreaseDegrees = 70;
  float edgeContrast = 1.3f;
  float regionContrast = 3.0f;
  float significance = 3;        // z: a difference within z standard errors is noise
  float clipSplit = 0.5f;        // faces (regions) whose clipped fractions differ by more never join
  float minAreaFraction = 1e-3f;
  float keepBrighter = 4;
};

struct Segmentation {
  std::vector<int32_t> faceObject;  // one per face, ids 0..objects-1 in order of each object's first face
  int objects = 0;
  size_t components = 0;     // connected components of the welded mesh
  size_t grownRegions = 0;   // regions after growing (steps 1-3)
  size_t mergedSmall = 0;    // small regions merged into a neighbour (step 4)
  size_t keptSmallBright = 0;  // small regions kept for their brightness
  size_t isolatedSmall = 0;    // small regions with no neighbour to join (separate small components)
};

// Per face, the index of its connected component (faces sharing an edge of the welded mesh), in
// order of each component's first face.
std::vector<uint32_t> connectedComponents(const TriangleMesh& mesh);

// `appearance` has one entry per face of `mesh` (all unobserved: geometry alone decides).
Segmentation segmentMesh(const TriangleMesh& mesh, const std::vector<FaceAppearance>& appearance,
                         const SegmentationOptions& options);

// A segmentation's file (prepare's segments.bin): a magic, the face count, one int32 object id per
// face of the mesh as loadMesh reads it. Written atomically.
void writeFaceObjects(const std::filesystem::path& file, const std::vector<int32_t>& faceObject);
// Throws relume::Error naming the file unless it holds exactly `faces` (> 0) ids, each below `faces`.
std::vector<int32_t> readFaceObjects(const std::filesystem::path& file, size_t faces);

}  // namespace relume
