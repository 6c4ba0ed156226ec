#include "io/export_scene.h"

#include <algorithm>

namespace relume {

std::vector<MeshData> objectSubmeshes(const MeshData& mesh, int objects) {
  std::vector<std::vector<uint32_t>> facesOf(objects);
  for (size_t f = 0; f < mesh.triangles.size(); ++f) {
    const int o = mesh.faceObject.empty() ? 0 : mesh.faceObject[f];
    if (o >= 0 && o < objects) facesOf[o].push_back(static_cast<uint32_t>(f));
  }
  std::vector<MeshData> subs(objects);
  std::vector<int> local(mesh.positions.size(), -1);  // reset after each object: O(faces + vertices) in all
  for (int o = 0; o < objects; ++o) {
    MeshData& sub = subs[o];
    std::vector<int> touched;
    for (uint32_t f : facesOf[o]) {
      Eigen::Vector3i tri;
      for (int k = 0; k < 3; ++k) {
        const int v = mesh.triangles[f][k];
        if (local[v] < 0) {
          local[v] = static_cast<int>(sub.positions.size());
          touched.push_back(v);
          sub.positions.push_back(mesh.positions[v]);
          if (!mesh.normals.empty()) sub.normals.push_back(mesh.normals[v]);
          if (!mesh.uvs.empty()) sub.uvs.push_back(mesh.uvs[v]);
        }
        tri[k] = local[v];
      }
      sub.triangles.push_back(tri);
    }
    for (int v : touched) local[v] = -1;
    // With one degenerate normal (zero, NaN) none is kept: importers then compute their own.
    if (!std::all_of(sub.normals.begin(), sub.normals.end(),
                     [](const Vec3& n) { return n.allFinite() && n.norm() > 1e-6f; }))
      sub.normals.clear();
  }
  return subs;
}

}  // namespace relume
