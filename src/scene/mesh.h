// Validated triangle mesh with per-face object ids (segmentation) and optional uv / normals.
#pragma once
#include <filesystem>

#include "io/mesh_data.h"

namespace relume {

struct TriangleMesh {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;  // per vertex, may be empty
  std::vector<Vec2> uvs;      // per vertex, may be empty
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int32_t> faceObject;  // always one per triangle
  std::vector<std::string> objectNames;  // from the file (OBJ groups), may be empty
  std::vector<float> faceArea;
  int objectCount = 1;
  size_t droppedDegenerate = 0;

  bool hasUv() const { return !uvs.empty(); }
  Vec3 faceNormal(size_t f) const;  // unit geometric normal, winding order
  MeshData toData() const;
};

// Drops degenerate triangles (zero area, repeated or non-finite vertices) and counts them;
// checks uv/normal counts. Throws relume::Error if nothing usable is left.
TriangleMesh buildMesh(MeshData data, const std::string& source);
TriangleMesh loadMesh(const std::filesystem::path& path);

}  // namespace relume
