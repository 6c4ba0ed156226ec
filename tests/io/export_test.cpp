// The exporters, read back by an independent reader: tinygltf's loader for the .glb (materials,
// extensions, uv, decoded texture), a small XML scan and relume's PLY reader for Mitsuba.
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "core/error.h"
#include "io/export_scene.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path tmpDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("relume_export_test_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// Three unit quads side by side: object 0 textured albedo, object 1 constant and emitting
// radiance 5 (above glTF's [0,1] factor), object 2 a textured emitter.
ExportScene threeQuads() {
  ExportScene s;
  for (int o = 0; o < 3; ++o) {
    const int v = static_cast<int>(s.mesh.positions.size());
    for (int k = 0; k < 4; ++k) {
      const Vec2 corner(k == 1 || k == 2 ? 1.0f : 0.0f, k >= 2 ? 1.0f : 0.0f);
      s.mesh.positions.push_back(Vec3(static_cast<float>(o) + corner.x(), corner.y(), 0.0f));
      s.mesh.normals.push_back(Vec3(0, 0, 2));  // not unit: the writer normalises
      s.mesh.uvs.push_back(Vec2((static_cast<float>(o) + corner.x()) / 3.0f, corner.y()));
    }
    s.mesh.triangles.push_back({v, v + 1, v + 2});
    s.mesh.triangles.push_back({v, v + 2, v + 3});
    s.mesh.faceObject.insert(s.mesh.faceObject.end(), 2, o);
  }
  s.albedo = Image(6, 2);
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 2; ++y) s.albedo.set(x, y, Color(0.05f * x, 0.5f, 0.9f - 0.1f * y));
  s.emission = Image(6, 2);
  s.emission.set(5, 1, Color(8, 4, 2));
  s.materials.resize(3);
  s.materials[0] = {"floor", Color::Constant(0.5f), true, 0.3f, 0.6f, 1.0f, Color::Zero(), false};
  s.materials[1] = {"lamp <1>", Color(0.2f, 0.3f, 0.4f), false, 0.9f, 0.25f, 0.25f, Color(5, 2.5f, 1), false};
  s.materials[2] = {"panel", Color::Constant(0.8f), false, 0.5f, 0.0f, 1.0f, Color::Zero(), true};
  return s;
}

double number(const tinygltf::Value& v) { return v.IsInt() ? v.Get<int>() : v.Get<double>(); }

}  // namespace

TEST(GltfWriter, ReadsBackWithMaterialsSpecularEmissionUvAndTexture) {
  const fs::path dir = tmpDir("glb");
  const ExportScene s = threeQuads();
  writeGlb(dir / "scene.glb", s);
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, (dir / "scene.glb").string())) << err;
  ASSERT_EQ(m.materials.size(), 3u);
  EXPECT_EQ(m.extensionsUsed, std::vector<std::string>({"KHR_materials_specular", "KHR_materials_emissive_strength"}));
  ASSERT_EQ(m.nodes.size(), 3u);
  for (int o = 0; o < 3; ++o) {
    const tinygltf::Material& mat = m.materials[o];
    const ExportMaterial& e = s.materials[o];
    EXPECT_EQ(mat.name, e.name);
    EXPECT_EQ(number(m.nodes[o].extras.Get("relume_object_id")), o);
    EXPECT_EQ(mat.pbrMetallicRoughness.metallicFactor, 0.0);
    EXPECT_NEAR(mat.pbrMetallicRoughness.roughnessFactor, e.roughness, 1e-6);
    // The spec's dielectric F0 = min(0.04 specularColorFactor, 1) specularFactor, F90 = specularFactor.
    const tinygltf::Value& spec = mat.extensions.at("KHR_materials_specular");
    const double f = number(spec.Get("specularFactor")), c = number(spec.Get("specularColorFactor").Get(1));
    EXPECT_NEAR(std::min(0.04 * c, 1.0) * f, 0.08 * e.specular, 1e-6) << e.name;
    EXPECT_NEAR(f, e.f90, 1e-6) << e.name;
    const bool textured = mat.pbrMetallicRoughness.baseColorTexture.index >= 0;
    EXPECT_EQ(textured, e.baseColorTextured);
    if (!textured) {
      EXPECT_NEAR(mat.pbrMetallicRoughness.baseColorFactor[2], e.baseColor[2], 1e-6);
    }
  }
  // Radiance 5 as factor (1, 0.5, 0.2) x strength 5.
  const tinygltf::Material& lamp = m.materials[1];
  const double strength = number(lamp.extensions.at("KHR_materials_emissive_strength").Get("emissiveStrength"));
  EXPECT_NEAR(lamp.emissiveFactor[0] * strength, 5.0, 1e-5);
  EXPECT_NEAR(lamp.emissiveFactor[2] * strength, 1.0, 1e-5);
  EXPECT_TRUE(m.materials[0].emissiveFactor == std::vector<double>({0, 0, 0}));
  // The textured emitter: texture = radiance / peak, strength = peak.
  const tinygltf::Material& panel = m.materials[2];
  ASSERT_GE(panel.emissiveTexture.index, 0);
  EXPECT_NEAR(number(panel.extensions.at("KHR_materials_emissive_strength").Get("emissiveStrength")), 8.0, 1e-5);
  const tinygltf::Image& emissive = m.images[m.textures[panel.emissiveTexture.index].source];
  EXPECT_EQ(emissive.image[4 * (1 * 6 + 5) + 0], 255);
  EXPECT_EQ(emissive.image[4 * (1 * 6 + 5) + 1], std::lround(linearToSrgb(0.5f) * 255));
  // The albedo texture decodes to the sRGB encoding of the linear albedo, row 0 at the top.
  const tinygltf::Image& albedo =
      m.images[m.textures[m.materials[0].pbrMetallicRoughness.baseColorTexture.index].source];
  ASSERT_EQ(albedo.width, 6);
  ASSERT_EQ(albedo.height, 2);
  const int comps = albedo.component;
  for (int x = 0; x < 6; ++x)
    for (int y = 0; y < 2; ++y)
      for (int k = 0; k < 3; ++k)
        EXPECT_EQ(albedo.image[comps * (y * 6 + x) + k], std::lround(linearToSrgb(s.albedo.at(x, y)[k]) * 255));
  // Geometry of object 1: its own 4 vertices with their uv, unit normals, 2 triangles.
  const tinygltf::Primitive& prim = m.meshes[m.nodes[1].mesh].primitives[0];
  const tinygltf::Accessor& uv = m.accessors[prim.attributes.at("TEXCOORD_0")];
  const tinygltf::Accessor& nrm = m.accessors[prim.attributes.at("NORMAL")];
  ASSERT_EQ(uv.count, 4u);
  EXPECT_EQ(m.accessors[prim.indices].count, 6u);
  const tinygltf::BufferView& uvView = m.bufferViews[uv.bufferView];
  const float* uvs = reinterpret_cast<const float*>(m.buffers[0].data.data() + uvView.byteOffset + uv.byteOffset);
  for (int k = 0; k < 4; ++k) {
    EXPECT_FLOAT_EQ(uvs[2 * k], s.mesh.uvs[4 + k].x());
    EXPECT_FLOAT_EQ(uvs[2 * k + 1], s.mesh.uvs[4 + k].y());
  }
  const tinygltf::BufferView& nView = m.bufferViews[nrm.bufferView];
  EXPECT_FLOAT_EQ(reinterpret_cast<const float*>(m.buffers[0].data.data() + nView.byteOffset + nrm.byteOffset)[2],
                  1.0f);
}

TEST(MitsubaWriter, OneShapePerObjectWithPrincipledParametersAndEmitters) {
  const fs::path dir = tmpDir("mitsuba");
  const ExportScene s = threeQuads();
  writeMitsubaScene(dir, s, 9);
  std::stringstream xml;
  xml << std::ifstream(dir / "scene.xml").rdbuf();
  const std::string text = xml.str();
  EXPECT_NE(text.find("<integer name=\"max_depth\" value=\"10\"/>"), std::string::npos);
  EXPECT_NE(text.find("id=\"lamp &lt;1&gt;\""), std::string::npos);  // names escaped
  const std::regex shapeRe(R"re(<shape type="ply" id="[^"]*">([\s\S]*?)</shape>)re");
  const std::regex fileRe(R"re(name="filename" value="([^"]+)")re"), roughRe(R"re(name="roughness" value="([^"]+)")re"),
      specRe(R"re(name="specular" value="([^"]+)")re");
  int o = 0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), shapeRe); it != std::sregex_iterator(); ++it, ++o) {
    ASSERT_LT(o, 3);
    const std::string body = (*it)[1];
    std::smatch mFile, mRough, mSpec;
    ASSERT_TRUE(std::regex_search(body, mFile, fileRe));
    ASSERT_TRUE(std::regex_search(body, mRough, roughRe));
    ASSERT_TRUE(std::regex_search(body, mSpec, specRe));
    EXPECT_FLOAT_EQ(std::stof(mRough[1]), s.materials[o].roughness);
    EXPECT_FLOAT_EQ(std::stof(mSpec[1]), s.materials[o].specular);
    const MeshData mesh = readPly(dir / mFile[1].str());
    EXPECT_EQ(mesh.triangles.size(), 2u);
    ASSERT_EQ(mesh.uvs.size(), 4u);
    EXPECT_EQ(mesh.uvs[1], s.mesh.uvs[4 * o + 1]);
    EXPECT_EQ(body.find(R"(<ref name="base_color" id="albedo"/>)") != std::string::npos,
              s.materials[o].baseColorTextured);
    EXPECT_EQ(body.find("<emitter type=\"area\">") != std::string::npos, o >= 1);
  }
  EXPECT_EQ(o, 3);
  EXPECT_NE(text.find("<rgb name=\"radiance\" value=\"5, 2.5, 1\"/>"), std::string::npos);
  EXPECT_NE(text.find(R"(<texture type="bitmap" id="emission">)"), std::string::npos);
  EXPECT_NE(text.find(R"(<ref name="radiance" id="emission"/>)"), std::string::npos);
  const Image emission = readImage(dir / "textures" / "emission.exr");
  EXPECT_TRUE((emission.at(5, 1) == Color(8, 4, 2)).all());
}

TEST(SrgbPng, SixteenBitKeepsWhatEightBitRoundsAway) {
  const fs::path dir = tmpDir("png");
  Image img(2, 1);
  img.set(0, 0, Color(0.002f, 0.2f, 0.7f));
  img.set(1, 0, Color(1.5f, -1.0f, 0.5f));  // clamped to [0,1]
  writeSrgbPng(dir / "a8.png", img, 8);
  writeSrgbPng(dir / "a16.png", img, 16);
  const Image a8 = readImage(dir / "a8.png"), a16 = readImage(dir / "a16.png");
  EXPECT_NEAR(a16.at(0, 0)[0], 0.002f, 2e-6f);
  EXPECT_GT(std::abs(a8.at(0, 0)[0] - 0.002f), 1e-4f);
  EXPECT_NEAR(a16.at(0, 0)[2], 0.7f, 1e-4f);
  EXPECT_LT((a16.at(1, 0) - Color(1, 0, 0.5f)).abs().maxCoeff(), 1e-4f);
  EXPECT_THROW(writeSrgbPng(dir / "bad.png", img, 12), Error);
}
