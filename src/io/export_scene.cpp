#include "io/export_scene.h"

#include <algorithm>

namespace relume {

MeshData objectSubmesh(const MeshData& mesh, int object) {
  MeshData sub;
  std::vector<int> local(mesh.positions.size(), -1);
  for (size_t f = 0; f < mesh.triangles.size(); ++f) {
    if ((mesh.faceObject.empty() ? 0 : mesh.faceObject[f]) != object) continue;
    Eigen::Vector3i tri;
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles[f][k];
      if (local[v] < 0) {
        local[v] = static_cast<int>(sub.positions.size());
        sub.positions.push_back(mesh.positions[v]);
        if (!mesh.normals.empty()) sub.normals.push_back(mesh.normals[v]);
        if (!mesh.uvs.empty()) sub.uvs.push_back(mesh.uvs[v]);
      }
      tri[k] = local[v];
    }
    sub.triangles.push_back(tri);
  }
  // With one degenerate normal (zero, NaN) none is kept: importers then compute their own.
  if (!std::all_of(sub.normals.begin(), sub.normals.end(), [](const Vec3& n) { return n.allFinite() && n.norm() > 1e-6f; }))
    sub.normals.clear();
  return sub;
}

}  // namespace relume
