// `relume export` on a synthetic scene: every object arrives in the .glb with its material, the
// Mitsuba scene holds every triangle, the textures round-trip at their stated precision.
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include "core/error.h"
#include "io/image.h"
#include "product/export.h"
#include "scenes/synth.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {
fs::path roomScene(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("relume_export_" + name);
  fs::remove_all(dir);
  saveSceneFile(dir / "scene" / "scene.json", makeSynthScene(SynthSceneKind::Room, 64).scene);
  return dir;
}
}  // namespace

TEST(Export, RoomArrivesInGltfMitsubaAndTextures) {
  const fs::path dir = roomScene("room");
  ExportOptions o;
  o.gltf = dir / "room.glb", o.mitsuba = dir / "mitsuba", o.textures = dir / "textures";
  exportScene(dir / "scene" / "scene.json", o);
  const SceneDescription truth = loadSceneFile(dir / "scene" / "scene.json");
  const Appearance& a = truth.appearance;

  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, o.gltf.string())) << err;
  ASSERT_EQ(static_cast<int>(m.nodes.size()), a.objectCount());
  size_t triangles = 0;
  for (const tinygltf::Node& node : m.nodes) {
    const int id = node.extras.Get("relume_object_id").Get<int>();
    const tinygltf::Material& mat = m.materials[m.meshes[node.mesh].primitives[0].material];
    EXPECT_EQ(mat.name, a.names[id]);
    EXPECT_NEAR(mat.pbrMetallicRoughness.roughnessFactor, a.roughness[id], 1e-6);
    EXPECT_EQ(mat.pbrMetallicRoughness.baseColorTexture.index >= 0, a.usesTexture(id));
    const Color e = a.emission[id];
    const double strength =
        mat.extensions.count("KHR_materials_emissive_strength")
            ? mat.extensions.at("KHR_materials_emissive_strength").Get("emissiveStrength").Get<double>()
            : 1.0;
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(mat.emissiveFactor[k] * strength, e[k], 1e-4 * (1 + e[k])) << a.names[id];
    triangles += m.accessors[m.meshes[node.mesh].primitives[0].indices].count / 3;
  }
  EXPECT_EQ(triangles, truth.mesh.triangles.size());

  size_t mitsubaTriangles = 0;
  for (const auto& entry : fs::directory_iterator(o.mitsuba / "meshes"))
    mitsubaTriangles += readPly(entry.path()).triangles.size();
  EXPECT_EQ(mitsubaTriangles, truth.mesh.triangles.size());
  EXPECT_TRUE(fs::exists(o.mitsuba / "scene.xml"));
  EXPECT_TRUE(fs::exists(o.mitsuba / "textures" / "albedo.exr"));

  const Image exr = readImage(o.textures / "albedo.exr"), png16 = readImage(o.textures / "albedo_srgb16.png"),
              png8 = readImage(o.textures / "albedo_srgb8.png");
  ASSERT_EQ(exr.rgb.size(), a.albedo.rgb.size());
  float err16 = 0, err8 = 0;
  for (size_t i = 0; i < exr.rgb.size(); ++i) {
    EXPECT_EQ(exr.rgb[i], a.albedo.rgb[i]);
    err16 = std::max(err16, std::abs(png16.rgb[i] - a.albedo.rgb[i]));
    err8 = std::max(err8, std::abs(png8.rgb[i] - a.albedo.rgb[i]));
  }
  EXPECT_LT(err16, 1e-4f);  // 16-bit sRGB: below 1e-4 linear everywhere in [0,1]
  EXPECT_LT(err8, 1e-2f);   // 8-bit sRGB: half a step of 1/255 at the top, in linear units
  EXPECT_GT(err8, err16);
}

TEST(Export, AcceptsAWorkFolderAndRejectsOneWithoutAResult) {
  const fs::path dir = roomScene("work");
  fs::create_directories(dir / "work");
  ExportOptions o;
  o.gltf = dir / "out.glb";
  try {
    exportScene(dir / "work", o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no result/scene.json"), std::string::npos) << e.what();
  }
  fs::rename(dir / "scene", dir / "work" / "result");
  exportScene(dir / "work", o);
  EXPECT_TRUE(fs::exists(o.gltf));
  EXPECT_THROW(exportScene(dir / "work", ExportOptions{}), Error);  // nothing to write
}
