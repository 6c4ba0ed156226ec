// Raw triangle mesh as read from disk, before any cleaning (the scene module validates it).
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/math.h"

namespace relume {

struct MeshData {
  std::vector<Vec3> positions;
  std::vector<Vec3> normals;  // empty or one per vertex
  std::vector<Vec2> uvs;      // empty or one per vertex; glTF convention (v down from the top)
  std::vector<Eigen::Vector3i> triangles;
  std::vector<int32_t> faceObject;       // empty (one object) or one per triangle
  std::vector<std::string> objectNames;  // optional names, index = object id (OBJ groups)
  size_t polygonsTriangulated = 0;       // faces with more than 3 vertices that were fan-split
};

// PLY: ascii, binary_little_endian, binary_big_endian. Throws relume::Error naming file and element.
MeshData readPly(const std::filesystem::path& path);
// Binary little-endian PLY with optional normals/uvs (as `s t`) and per-face `object_id`. Atomic.
void writePly(const std::filesystem::path& path, const MeshData& mesh);
// Wavefront OBJ via tinyobjloader; each group/object becomes a segment.
MeshData readObj(const std::filesystem::path& path);
// Dispatch on extension.
MeshData readMesh(const std::filesystem::path& path);

}  // namespace relume
