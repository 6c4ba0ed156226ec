#include <tiny_gltf.h>

#include <algorithm>
#include <cstring>
#include <sstream>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/export_scene.h"

namespace relume {

namespace {

// Appends raw bytes to the single binary buffer (4-byte aligned, as accessors require) and
// returns the buffer view's index.
int addBufferView(tinygltf::Model& m, const void* data, size_t bytes, int target) {
  auto& buf = m.buffers[0].data;
  buf.resize((buf.size() + 3) & ~size_t{3});
  tinygltf::BufferView view;
  view.buffer = 0;
  view.byteOffset = buf.size();
  view.byteLength = bytes;
  view.target = target;
  buf.resize(buf.size() + bytes);
  std::memcpy(buf.data() + view.byteOffset, data, bytes);
  m.bufferViews.push_back(view);
  return static_cast<int>(m.bufferViews.size()) - 1;
}

template <typename Vec>
int addFloatAccessor(tinygltf::Model& m, const std::vector<Vec>& values, int type, bool withBounds) {
  constexpr int n = Vec::RowsAtCompileTime;
  std::vector<float> flat;
  flat.reserve(values.size() * n);
  for (const Vec& v : values)
    for (int k = 0; k < n; ++k) flat.push_back(v[k]);
  tinygltf::Accessor a;
  a.bufferView = addBufferView(m, flat.data(), flat.size() * sizeof(float), TINYGLTF_TARGET_ARRAY_BUFFER);
  a.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  a.count = values.size();
  a.type = type;
  if (withBounds) {  // the spec requires min/max on POSITION
    Vec lo = values[0], hi = values[0];
    for (const Vec& v : values) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
    a.minValues.assign(lo.data(), lo.data() + n);
    a.maxValues.assign(hi.data(), hi.data() + n);
  }
  m.accessors.push_back(a);
  return static_cast<int>(m.accessors.size()) - 1;
}

int addIndexAccessor(tinygltf::Model& m, const std::vector<Eigen::Vector3i>& triangles) {
  std::vector<uint32_t> idx;
  idx.reserve(triangles.size() * 3);
  for (const auto& t : triangles)
    for (int k = 0; k < 3; ++k) idx.push_back(static_cast<uint32_t>(t[k]));
  tinygltf::Accessor a;
  a.bufferView = addBufferView(m, idx.data(), idx.size() * sizeof(uint32_t), TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER);
  a.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  a.count = idx.size();
  a.type = TINYGLTF_TYPE_SCALAR;
  m.accessors.push_back(a);
  return static_cast<int>(m.accessors.size()) - 1;
}

// An sRGB PNG embedded in the buffer, with a bilinear clamped sampler; returns the texture index.
int addPngTexture(tinygltf::Model& m, const Image& image, const std::string& name) {
  const std::vector<uint8_t> png = encodeSrgbPng(image, 8);
  tinygltf::Image img;
  img.name = name;
  img.mimeType = "image/png";
  img.bufferView = addBufferView(m, png.data(), png.size(), 0);
  m.images.push_back(img);
  if (m.samplers.empty()) {
    tinygltf::Sampler s;
    s.magFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    s.minFilter = TINYGLTF_TEXTURE_FILTER_LINEAR;
    s.wrapS = s.wrapT = TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE;
    m.samplers.push_back(s);
  }
  tinygltf::Texture t;
  t.source = static_cast<int>(m.images.size()) - 1;
  t.sampler = 0;
  m.textures.push_back(t);
  return static_cast<int>(m.textures.size()) - 1;
}

tinygltf::Value number(double v) { return tinygltf::Value(v); }
tinygltf::Value triple(const Color& c) {
  return tinygltf::Value(tinygltf::Value::Array{number(c[0]), number(c[1]), number(c[2])});
}

// Emission: emissiveFactor in [0,1] times emissiveStrength. A texture holds radiance / peak (PNG
// cannot exceed 1), the strength restores the peak.
tinygltf::Material material(const ExportMaterial& em, int albedoTexture, int emissionTexture, float emissionPeak) {
  tinygltf::Material mat;
  mat.name = em.name;
  mat.doubleSided = true;
  auto& pbr = mat.pbrMetallicRoughness;
  pbr.metallicFactor = 0.0;
  pbr.roughnessFactor = em.roughness;
  if (em.baseColorTextured && albedoTexture >= 0) {
    pbr.baseColorTexture.index = albedoTexture;
  } else {
    pbr.baseColorFactor = {em.baseColor[0], em.baseColor[1], em.baseColor[2], 1.0};
  }
  // F0 = min(0.04 c, 1) f = 0.08 s and F90 = f: c = 2 s / f90. Blender's importer reads only c
  // (Specular = luminance(c) * 0.04 / 0.08 = s) and keeps F90 = 1, exact for principled-v1.
  const double color = em.f90 > 0 ? 2.0 * em.specular / em.f90 : 0.0;
  mat.extensions["KHR_materials_specular"] = tinygltf::Value(tinygltf::Value::Object{
      {"specularFactor", number(em.f90)}, {"specularColorFactor", triple(Color::Constant(static_cast<float>(color)))}});
  Color factor = em.emission;
  float strength = 1.0f;
  if (em.emissionTextured && emissionTexture >= 0) {
    mat.emissiveTexture.index = emissionTexture;
    factor = Color::Ones();
    strength = emissionPeak;
  } else if (factor.maxCoeff() > 1.0f) {
    strength = factor.maxCoeff();
    factor /= strength;
  }
  if (factor.maxCoeff() > 0.0f) {
    mat.emissiveFactor = {factor[0], factor[1], factor[2]};
    if (strength != 1.0f)
      mat.extensions["KHR_materials_emissive_strength"] =
          tinygltf::Value(tinygltf::Value::Object{{"emissiveStrength", number(strength)}});
  }
  return mat;
}

}  // namespace

void writeGlb(const std::filesystem::path& path, const ExportScene& scene) {
  tinygltf::Model m;
  m.asset.version = "2.0";
  m.asset.generator = "relume";
  m.buffers.resize(1);
  const bool anyAlbedoTexture = std::any_of(scene.materials.begin(), scene.materials.end(),
                                            [](const ExportMaterial& e) { return e.baseColorTextured; });
  const bool anyEmissionTexture = std::any_of(scene.materials.begin(), scene.materials.end(),
                                              [](const ExportMaterial& e) { return e.emissionTextured; });
  if ((anyAlbedoTexture && scene.albedo.rgb.empty()) || (anyEmissionTexture && scene.emission.rgb.empty()))
    fail("{}: a material is textured but the scene has no texture", path.string());
  if ((anyAlbedoTexture || anyEmissionTexture) && scene.mesh.uvs.empty())
    fail("{}: textured materials need a mesh with uv", path.string());
  const int albedoTexture = anyAlbedoTexture ? addPngTexture(m, scene.albedo, "albedo") : -1;
  float emissionPeak = 0.0f;
  int emissionTexture = -1;
  if (anyEmissionTexture) {
    for (float v : scene.emission.rgb) emissionPeak = std::max(emissionPeak, v);
    Image normalised = scene.emission;
    for (float& v : normalised.rgb) v = emissionPeak > 0 ? v / emissionPeak : 0.0f;
    emissionTexture = addPngTexture(m, normalised, "emission");
  }
  tinygltf::Scene gltfScene;
  const std::vector<MeshData> submeshes = objectSubmeshes(scene.mesh, static_cast<int>(scene.materials.size()));
  for (size_t o = 0; o < scene.materials.size(); ++o) {
    const MeshData& sub = submeshes[o];
    if (sub.triangles.empty()) continue;
    m.materials.push_back(material(scene.materials[o], albedoTexture, emissionTexture, emissionPeak));
    tinygltf::Primitive prim;
    prim.mode = TINYGLTF_MODE_TRIANGLES;
    prim.material = static_cast<int>(m.materials.size()) - 1;
    prim.attributes["POSITION"] = addFloatAccessor(m, sub.positions, TINYGLTF_TYPE_VEC3, true);
    if (!sub.normals.empty()) {  // the spec requires unit length
      std::vector<Vec3> unit(sub.normals.size());
      for (size_t i = 0; i < unit.size(); ++i) unit[i] = sub.normals[i].normalized();
      prim.attributes["NORMAL"] = addFloatAccessor(m, unit, TINYGLTF_TYPE_VEC3, false);
    }
    if (!sub.uvs.empty()) prim.attributes["TEXCOORD_0"] = addFloatAccessor(m, sub.uvs, TINYGLTF_TYPE_VEC2, false);
    prim.indices = addIndexAccessor(m, sub.triangles);
    tinygltf::Mesh mesh;
    mesh.name = scene.materials[o].name;
    mesh.primitives.push_back(prim);
    m.meshes.push_back(mesh);
    tinygltf::Node node;
    node.name = scene.materials[o].name;
    node.mesh = static_cast<int>(m.meshes.size()) - 1;
    // Importers keep extras (Blender: custom properties), so a consumer can map nodes to objects.
    node.extras = tinygltf::Value(tinygltf::Value::Object{{"relume_object_id", tinygltf::Value(static_cast<int>(o))}});
    m.nodes.push_back(node);
    gltfScene.nodes.push_back(static_cast<int>(m.nodes.size()) - 1);
  }
  m.scenes.push_back(gltfScene);
  for (const char* ext : {"KHR_materials_specular", "KHR_materials_emissive_strength"})
    if (std::any_of(m.materials.begin(), m.materials.end(),
                    [&](const tinygltf::Material& mat) { return mat.extensions.count(ext) > 0; }))
      m.extensionsUsed.push_back(ext);
  m.defaultScene = 0;
  std::ostringstream out;
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&m, out, false, true)) fail("{}: cannot encode glTF", path.string());
  writeTextAtomically(path, out.str());
}

}  // namespace relume
