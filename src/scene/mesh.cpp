#include "scene/mesh.h"

#include <spdlog/spdlog.h>

#include "core/error.h"

namespace relume {

Vec3 TriangleMesh::faceNormal(size_t f) const {
  const auto& t = triangles[f];
  return (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]).normalized();
}

MeshData TriangleMesh::toData() const {
  MeshData d;
  d.positions = positions;
  d.normals = normals;
  d.uvs = uvs;
  d.triangles = triangles;
  d.faceObject = faceObject;
  d.objectNames = objectNames;
  return d;
}

TriangleMesh buildMesh(MeshData data, const std::string& source) {
  TriangleMesh m;
  const size_t nv = data.positions.size();
  if (!data.normals.empty() && data.normals.size() != nv) fail("{}: {} normals for {} vertices", source, data.normals.size(), nv);
  if (!data.uvs.empty() && data.uvs.size() != nv) fail("{}: {} uvs for {} vertices", source, data.uvs.size(), nv);
  if (!data.faceObject.empty() && data.faceObject.size() != data.triangles.size())
    fail("{}: {} object ids for {} faces", source, data.faceObject.size(), data.triangles.size());
  m.objectNames = std::move(data.objectNames);
  m.positions = std::move(data.positions);
  m.normals = std::move(data.normals);
  m.uvs = std::move(data.uvs);
  bool uvValid = !m.uvs.empty();
  for (const Vec2& uv : m.uvs) uvValid = uvValid && uv.allFinite() && uv.minCoeff() >= -1e-4f && uv.maxCoeff() <= 1.0001f;
  if (!m.uvs.empty() && !uvValid) {
    spdlog::warn("{}: uv coordinates outside [0,1] or non-finite; ignoring them", source);
    m.uvs.clear();
  }
  for (Vec3& n : m.normals) {
    const float len = n.norm();
    n = (len > 0 && std::isfinite(len)) ? Vec3(n / len) : Vec3::Zero();
  }
  m.triangles.reserve(data.triangles.size());
  for (size_t f = 0; f < data.triangles.size(); ++f) {
    const auto& t = data.triangles[f];
    for (int k = 0; k < 3; ++k)
      if (t[k] < 0 || static_cast<size_t>(t[k]) >= nv) fail("{}: face {} vertex index {} out of range", source, f, t[k]);
    const float area = 0.5f * (m.positions[t[1]] - m.positions[t[0]]).cross(m.positions[t[2]] - m.positions[t[0]]).norm();
    if (!(area > 1e-12f) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++m.droppedDegenerate;
      continue;
    }
    m.triangles.push_back(t);
    m.faceArea.push_back(area);
    m.faceObject.push_back(data.faceObject.empty() ? 0 : data.faceObject[f]);
  }
  if (m.triangles.empty()) fail("{}: every triangle is degenerate", source);
  if (m.droppedDegenerate) spdlog::warn("{}: dropped {} degenerate triangles", source, m.droppedDegenerate);
  m.objectCount = 1 + *std::max_element(m.faceObject.begin(), m.faceObject.end());
  return m;
}

TriangleMesh loadMesh(const std::filesystem::path& path) { return buildMesh(readMesh(path), path.string()); }

}  // namespace relume
