#include "product/scene_edit.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <string_view>

#include "core/error.h"
#include "io/json.h"

namespace relume {
namespace {

namespace fs = std::filesystem;

// A typo must not be silently ignored: every key is one the schema knows.
void checkKeys(const Json& o, std::initializer_list<std::string_view> allowed, const std::string& where) {
  if (!o.is_object()) fail("{}: must be an object", where);
  for (const auto& [key, value] : o.items())
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      std::string list;
      for (std::string_view k : allowed) list += fmt::format("{}{}", list.empty() ? "" : ", ", k);
      fail("{}: unknown key '{}' (allowed: {})", where, key, list);
    }
}

float finiteNumber(const Json& v, const std::string& where, const char* key) {
  if (!v.is_number()) fail("{}: '{}' must be a number", where, key);
  const float f = static_cast<float>(v.get<double>());
  if (!std::isfinite(f)) fail("{}: '{}' is not finite", where, key);
  return f;
}

Vec3 vec3(const Json& o, const char* key, const std::string& where) {
  if (!o.contains(key)) fail("{}: needs '{}' [x, y, z]", where, key);
  const Json& v = o[key];
  if (!v.is_array() || v.size() != 3) fail("{}: '{}' must be [x, y, z]", where, key);
  return {finiteNumber(v[0], where, key), finiteNumber(v[1], where, key), finiteNumber(v[2], where, key)};
}

int objectOf(const Json& o, const Appearance& a, const std::string& where) {
  if (o.contains("id")) {
    const Json& id = o["id"];
    if (!id.is_number_integer()) fail("{}: 'id' must be an integer", where);
    if (id.is_number_unsigned() ? id.get<uint64_t>() >= static_cast<uint64_t>(a.objectCount())
                                : (id.get<int64_t>() < 0 || id.get<int64_t>() >= a.objectCount()))
      fail("{}: no object with id {} (objects 0..{})", where, id.dump(), a.objectCount() - 1);
    return static_cast<int>(id.get<int64_t>());
  }
  if (o.contains("name")) {
    if (!o["name"].is_string()) fail("{}: 'name' must be a string", where);
    const std::string name = o["name"].get<std::string>();
    const auto it = std::find(a.names.begin(), a.names.end(), name);
    if (it == a.names.end()) fail("{}: no object named '{}'", where, name);
    if (std::find(it + 1, a.names.end(), name) != a.names.end())
      fail("{}: several objects are named '{}'; use 'id'", where, name);
    return static_cast<int>(it - a.names.begin());
  }
  fail("{}: needs 'id' or 'name'", where);
}

void editObject(const Json& o, Appearance& a, const std::string& where) {
  checkKeys(o, {"id", "name", "albedo", "roughness", "specular", "emission", "emission_scale"}, where);
  const int id = objectOf(o, a, where);
  readConstantFields(o, id, where, a);
  if (o.contains("emission")) a.emissionTextureOf[id] = -1;  // a constant replaces the emission texture
  if (o.contains("emission_scale")) {
    const float k = finiteNumber(o["emission_scale"], where, "emission_scale");
    if (k < 0) fail("{}: 'emission_scale' is {}, must be >= 0", where, k);
    a.emission[id] *= k;
    if (a.emissionTextureOf[id] >= 0)
      for (float& v : a.emissionTextures[a.emissionTextureOf[id]].rgb) v *= k;
    requireEmissionBound(a, fmt::format("{}: 'emission_scale' {:g}", where, k));
  }
}

// Corners center -/+ edge_u/2 -/+ edge_v/2; emits along edge_u x edge_v.
MeshData rectangle(const Json& r, const std::string& where) {
  checkKeys(r, {"center", "edge_u", "edge_v"}, where);
  const Vec3 c = vec3(r, "center", where), u = 0.5f * vec3(r, "edge_u", where), v = 0.5f * vec3(r, "edge_v", where);
  if (u.cross(v).norm() <= 0.0f) fail("{}: edge_u and edge_v must span a rectangle", where);
  MeshData m;
  m.positions = {c - u - v, c + u - v, c + u + v, c - u + v};
  m.triangles = {{0, 1, 2}, {0, 2, 3}};
  return m;
}

MeshData meshFile(const Json& e, const fs::path& editDir, const std::string& where) {
  if (!e["mesh"].is_string()) fail("{}: 'mesh' must be a file name (PLY or OBJ)", where);
  MeshData m = readMesh(editDir / e["mesh"].get<std::string>());
  const float scale = e.contains("scale") ? finiteNumber(e["scale"], where, "scale") : 1.0f;
  if (!(scale > 0)) fail("{}: 'scale' must be > 0", where);
  const Vec3 t = e.contains("translate") ? vec3(e, "translate", where) : Vec3::Zero();
  for (Vec3& p : m.positions) p = scale * p + t;
  // Within the cameras' bound (capture/transforms.cpp): farther, areas and ray distances overflow.
  constexpr float kMaxCoordinate = 1e6f;
  for (size_t v = 0; v < m.positions.size(); ++v)
    if (!(m.positions[v].cwiseAbs().maxCoeff() <= kMaxCoordinate))
      fail("{}: 'scale' and 'translate' put vertex {} at ({:g}, {:g}, {:g}), beyond +-{:g} m", where, v,
           m.positions[v].x(), m.positions[v].y(), m.positions[v].z(), kMaxCoordinate);
  return m;
}

// Appends `part` as object `object`, matching the scene's vertex attributes: uv (0,0) where the
// scene has an atlas (the object's albedo is a constant), and where the scene has normals, the
// part's own or else flat ones (each face gets its vertices).
void appendPart(MeshData& scene, const MeshData& part, int object) {
  const bool flat = !scene.normals.empty() && part.normals.empty();
  auto addVertex = [&](int v, const Vec3& faceNormal) {
    scene.positions.push_back(part.positions[v]);
    if (!scene.normals.empty()) scene.normals.push_back(flat ? faceNormal : part.normals[v]);
    if (!scene.uvs.empty()) scene.uvs.push_back(Vec2::Zero());
    return static_cast<int>(scene.positions.size()) - 1;
  };
  if (scene.faceObject.empty()) scene.faceObject.assign(scene.triangles.size(), 0);
  const int base = static_cast<int>(scene.positions.size());
  if (!flat)
    for (size_t v = 0; v < part.positions.size(); ++v) addVertex(static_cast<int>(v), Vec3::Zero());
  for (const Eigen::Vector3i& t : part.triangles) {
    Eigen::Vector3i tri = t.array() + base;
    if (flat) {
      const Vec3 n =
          (part.positions[t[1]] - part.positions[t[0]]).cross(part.positions[t[2]] - part.positions[t[0]]).normalized();
      for (int k = 0; k < 3; ++k) tri[k] = addVertex(t[k], n);
    }
    scene.triangles.push_back(tri);
    scene.faceObject.push_back(object);
  }
}

void applyEdit(SceneDescription& s, const Json& j, const fs::path& file) {
  const std::string name = file.string();
  checkKeys(j, {"objects", "add"}, name);
  Appearance& a = s.appearance;
  if (j.contains("objects")) {
    if (!j["objects"].is_array()) fail("{}: 'objects' must be an array", name);
    for (size_t i = 0; i < j["objects"].size(); ++i)
      editObject(j["objects"][i], a, fmt::format("{}: objects[{}]", name, i));
  }
  if (!j.contains("add")) return;
  if (!j["add"].is_array()) fail("{}: 'add' must be an array", name);
  MeshData data = s.mesh.toData();
  const int firstAdded = a.objectCount();
  for (size_t i = 0; i < j["add"].size(); ++i) {
    const Json& e = j["add"][i];
    const std::string where = fmt::format("{}: add[{}]", name, i);
    checkKeys(e, {"rectangle", "mesh", "scale", "translate", "name", "albedo", "roughness", "specular", "emission"},
              where);
    if (e.contains("rectangle") == e.contains("mesh")) fail("{}: needs exactly one of 'rectangle' and 'mesh'", where);
    const MeshData part =
        e.contains("rectangle") ? rectangle(e["rectangle"], where) : meshFile(e, file.parent_path(), where);
    const int id = a.addObject(e.contains("name") ? e["name"].get<std::string>() : fmt::format("added{}", i));
    readConstantFields(e, id, where, a);
    appendPart(data, part, id);
  }
  s.mesh = buildMesh(std::move(data), name);
  std::vector<uint8_t> present(a.objectCount(), 0);
  for (int32_t o : s.mesh.faceObject) present[o] = 1;
  for (int o = firstAdded; o < a.objectCount(); ++o)
    if (!present[o]) fail("{}: add[{}] has no usable triangle", name, o - firstAdded);
}

}  // namespace

void applySceneEdit(SceneDescription& scene, const fs::path& editFile) {
  const Json j = readJson(editFile);
  withJsonErrors(editFile, [&] { applyEdit(scene, j, editFile); });
}

}  // namespace relume
