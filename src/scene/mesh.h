// Validated triangle mesh with per-face object ids (segmentation) and optional uv / normals.
#pragma once
#include <filesystem>
#include <optional>

#include "io/mesh_data.h"

namespace relume {

struct TriangleMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;  // per vertex, may be empty
  std::vector<Vec2> uvs;      // per vertex, may be empty
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int32_t> faceObject;       // always one per triangle
  std::vector<std::string> objectNames;  // from the file (OBJ groups), may be empty
  std::vector<float> faceArea;
  int objectCount = 1;
  size_t droppedDegenerate = 0;  // zero area (relative to the longest edge), repeated or non-finite vertices
  size_t droppedCoincident = 0;  // a second face on the same three vertex positions (any order or winding)

  bool hasUv() const { return !uvs.empty(); }
  Vec3 faceNormal(size_t f) const;  // unit geometric normal, winding order
  // The vertex normals of face f interpolated at barycentrics `b` (b0, b1, b2), unit length, on the
  // side the vertex normals point to (not flipped to the winding side). Empty when the mesh has no
  // normals or the interpolation is unreliable: its length is below kMinShadingNormalLength (vertex
  // normals that disagree by more than ~120 degrees cancel out, down to zero and NaN) or it is more
  // than acos(kMinShadingCosine) = 60 degrees from the geometric normal's line. Callers then use the
  // geometric normal.
  std::optional<Vec3> shadingNormal(size_t f, const Vec3& b) const;
  // The same test on given vertex normals n[3] and unit geometric normal ng (what a renderer keeps
  // per face, so a hit need not gather them from the mesh arrays).
  static std::optional<Vec3> shadingNormal(const Vec3 n[3], const Vec3& b, const Vec3& ng);
  static constexpr float kMinShadingNormalLength = 0.5f, kMinShadingCosine = 0.5f;
  MeshData toData() const;
};

// Drops degenerate triangles (zero area, repeated or non-finite vertices) and coincident ones (the
// same three positions as an earlier face), counting each kind; checks uv/normal counts. Throws relume::Error if
// nothing usable is left.
TriangleMesh buildMesh(MeshData data, const std::string& source);
TriangleMesh loadMesh(const std::filesystem::path& path);

}  // namespace relume
