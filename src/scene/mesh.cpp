#include "scene/mesh.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <numeric>

#include "core/error.h"

namespace relume {

Vec3 TriangleMesh::faceNormal(size_t f) const {
  const auto& t = triangles[f];
  return (positions[t[1]] - positions[t[0]]).cross(positions[t[2]] - positions[t[0]]).normalized();
}

std::optional<Vec3> TriangleMesh::shadingNormal(size_t f, const Vec3& b) const {
  if (normals.empty()) return std::nullopt;
  const auto& t = triangles[f];
  const Vec3 n[3] = {normals[t[0]], normals[t[1]], normals[t[2]]};
  return shadingNormal(n, b, faceNormal(f));
}

std::optional<Vec3> TriangleMesh::shadingNormal(const Vec3 n[3], const Vec3& b, const Vec3& ng) {
  const Vec3 sum = b[0] * n[0] + b[1] * n[1] + b[2] * n[2];
  const float len = sum.norm();
  if (!(len >= kMinShadingNormalLength) || !std::isfinite(len)) return std::nullopt;
  const Vec3 unit = sum / len;
  if (!(std::abs(unit.dot(ng)) >= kMinShadingCosine)) return std::nullopt;
  return unit;
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
  if (!data.normals.empty() && data.normals.size() != nv)
    fail("{}: {} normals for {} vertices", source, data.normals.size(), nv);
  if (!data.uvs.empty() && data.uvs.size() != nv) fail("{}: {} uvs for {} vertices", source, data.uvs.size(), nv);
  if (!data.faceObject.empty() && data.faceObject.size() != data.triangles.size())
    fail("{}: {} object ids for {} faces", source, data.faceObject.size(), data.triangles.size());
  m.objectNames = std::move(data.objectNames);
  m.positions = std::move(data.positions);
  m.normals = std::move(data.normals);
  m.uvs = std::move(data.uvs);
  bool uvValid = !m.uvs.empty();
  for (const Vec2& uv : m.uvs)
    uvValid = uvValid && uv.allFinite() && uv.minCoeff() >= -1e-4f && uv.maxCoeff() <= 1.0001f;
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
      if (t[k] < 0 || static_cast<size_t>(t[k]) >= nv)
        fail("{}: face {} vertex index {} out of range", source, f, t[k]);
    const Vec3 p0 = m.positions[t[0]], p1 = m.positions[t[1]], p2 = m.positions[t[2]];
    const float area = 0.5f * (p1 - p0).cross(p2 - p0).norm();
    // Zero area also relative to the longest edge: a needle whose height is below 1e-6 of its
    // length has no texel, no usable normal and a uv map of zero area.
    const float longest = std::max({(p1 - p0).squaredNorm(), (p2 - p1).squaredNorm(), (p0 - p2).squaredNorm()});
    if (!(area > 1e-12f) || !(2 * area > 1e-6f * longest) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      ++m.droppedDegenerate;
      continue;
    }
    m.triangles.push_back(t);
    m.faceArea.push_back(area);
    m.faceObject.push_back(data.faceObject.empty() ? 0 : data.faceObject[f]);
  }
  // Coincident faces (a face listed twice, or an OBJ polygon that repeats a vertex and so fans into
  // the same triangle twice): same three positions in any order; the first one in file order stays.
  {
    using Key = std::array<float, 9>;
    std::vector<Key> keys(m.triangles.size());
    for (size_t f = 0; f < keys.size(); ++f) {
      std::array<Vec3, 3> p{m.positions[m.triangles[f][0]], m.positions[m.triangles[f][1]],
                            m.positions[m.triangles[f][2]]};
      std::sort(p.begin(), p.end(), [](const Vec3& a, const Vec3& b) {
        return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
      });
      for (int k = 0; k < 3; ++k) std::copy(p[k].data(), p[k].data() + 3, keys[f].begin() + 3 * k);
    }
    std::vector<uint32_t> order(keys.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
    std::vector<char> drop(keys.size(), 0);
    for (size_t i = 1; i < order.size(); ++i)
      if (keys[order[i]] == keys[order[i - 1]]) drop[order[i]] = 1;  // stable: the earlier face is order[i - 1]
    size_t kept = 0;
    for (size_t f = 0; f < keys.size(); ++f) {
      if (drop[f]) {
        ++m.droppedCoincident;
        continue;
      }
      m.triangles[kept] = m.triangles[f], m.faceArea[kept] = m.faceArea[f], m.faceObject[kept] = m.faceObject[f];
      ++kept;
    }
    m.triangles.resize(kept), m.faceArea.resize(kept), m.faceObject.resize(kept);
  }
  if (m.triangles.empty()) fail("{}: every triangle is degenerate", source);
  if (m.droppedDegenerate) spdlog::warn("{}: dropped {} degenerate triangles", source, m.droppedDegenerate);
  if (m.droppedCoincident)
    spdlog::warn("{}: dropped {} coincident triangles (same vertex positions as an earlier face)", source,
                 m.droppedCoincident);
  m.objectCount = 1 + *std::max_element(m.faceObject.begin(), m.faceObject.end());
  return m;
}

TriangleMesh loadMesh(const std::filesystem::path& path) { return buildMesh(readMesh(path), path.string()); }

}  // namespace relume
