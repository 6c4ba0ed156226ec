#include <tiny_obj_loader.h>

#include <map>
#include <tuple>

#include "core/error.h"
#include "io/input_file.h"
#include "io/mesh_data.h"

namespace relume {

MeshData readObj(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string text = readRegularFile(path, "an OBJ mesh");
  tinyobj::ObjReaderConfig config;
  config.triangulate = false;  // fan-triangulate ourselves, like PLY polygons
  config.vertex_color = false;
  tinyobj::ObjReader reader;
  // Parsed from memory with an empty material library: materials are not used, and an `mtllib`
  // line must not make the reader open arbitrary paths (a FIFO, /dev/zero).
  if (!reader.ParseFromString(text, "", config)) {
    std::string msg = reader.Error();
    while (!msg.empty() && (msg.back() == '\n' || msg.back() == '\r')) msg.pop_back();
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    fail("{}: malformed OBJ: {}", file, msg.empty() ? "parse error" : msg);
  }
  const tinyobj::attrib_t& attrib = reader.GetAttrib();
  MeshData mesh;
  const size_t nv = attrib.vertices.size() / 3;
  // OBJ indexes positions, normals and uvs separately; we keep one index per corner as a new
  // vertex keyed by the (position, normal, uv) triple so attributes stay per-vertex.
  std::map<std::tuple<int, int, int>, int> remap;
  const bool anyUv = !attrib.texcoords.empty(), anyN = !attrib.normals.empty();
  for (const tinyobj::shape_t& shape : reader.GetShapes()) {
    const int objectId = static_cast<int>(mesh.objectNames.size());
    mesh.objectNames.push_back(shape.name.empty() ? fmt::format("object{}", objectId) : shape.name);
    size_t offset = 0;
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
      const size_t n = shape.mesh.num_face_vertices[f];
      std::vector<int> corner(n);
      for (size_t k = 0; k < n; ++k) {
        const tinyobj::index_t idx = shape.mesh.indices[offset + k];
        if (idx.vertex_index < 0 || static_cast<size_t>(idx.vertex_index) >= nv)
          fail("{}: face {} of '{}' references vertex {} out of range", file, f, shape.name, idx.vertex_index);
        auto key = std::make_tuple(idx.vertex_index, anyN ? idx.normal_index : -1, anyUv ? idx.texcoord_index : -1);
        auto [it, inserted] = remap.try_emplace(key, static_cast<int>(mesh.positions.size()));
        if (inserted) {
          const float* p = &attrib.vertices[3 * static_cast<size_t>(idx.vertex_index)];
          mesh.positions.emplace_back(p[0], p[1], p[2]);
          if (anyN) {
            const bool ok =
                idx.normal_index >= 0 && 3 * static_cast<size_t>(idx.normal_index) + 2 < attrib.normals.size();
            mesh.normals.push_back(ok ? Vec3(attrib.normals[3 * idx.normal_index],
                                             attrib.normals[3 * idx.normal_index + 1],
                                             attrib.normals[3 * idx.normal_index + 2])
                                      : Vec3::Zero());
          }
          if (anyUv) {
            const bool ok =
                idx.texcoord_index >= 0 && 2 * static_cast<size_t>(idx.texcoord_index) + 1 < attrib.texcoords.size();
            // OBJ's v points up; ours (glTF) points down.
            mesh.uvs.push_back(
                ok ? Vec2(attrib.texcoords[2 * idx.texcoord_index], 1.0f - attrib.texcoords[2 * idx.texcoord_index + 1])
                   : Vec2(-1, -1));
          }
        }
        corner[k] = it->second;
      }
      offset += n;
      if (n > 3) ++mesh.polygonsTriangulated;
      for (size_t k = 1; k + 1 < n; ++k) {
        mesh.triangles.emplace_back(corner[0], corner[k], corner[k + 1]);
        mesh.faceObject.push_back(objectId);
      }
    }
  }
  if (mesh.triangles.empty()) fail("{}: OBJ has no faces", file);
  return mesh;
}

MeshData readMesh(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  if (ext == ".ply") return readPly(path);
  if (ext == ".obj") return readObj(path);
  fail("{}: unsupported mesh format '{}' (expected .ply or .obj)", path.string(), ext);
}

}  // namespace relume
