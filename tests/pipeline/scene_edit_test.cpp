// `relume render --edit`: what each edit does to the scene, one-line errors, and the relight test
// (a reconstruction edited against the ground truth edited the same way, built independently).
#include <gtest/gtest.h>

#include <fstream>

#include "core/error.h"
#include "io/atomic_file.h"
#include "pipeline/scene_edit.h"
#include "pipeline/synth.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path tmpDir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("relume_edit_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

SceneDescription edited(SceneDescription s, const fs::path& dir, const std::string& json) {
  writeTextAtomically(dir / "edit.json", json);
  applySceneEdit(s, dir / "edit.json");
  return s;
}

std::string errorOf(const SceneDescription& s, const fs::path& dir, const std::string& json) {
  try {
    edited(s, dir, json);
  } catch (const Error& e) {
    return e.what();
  }
  return "<no error>";
}

int idOf(const Appearance& a, const std::string& name) {
  return static_cast<int>(std::find(a.names.begin(), a.names.end(), name) - a.names.begin());
}

}  // namespace

TEST(SceneEdit, SwitchesLightsChangesMaterialsAndAppendsGeometry) {
  const fs::path dir = tmpDir("apply");
  const SceneDescription room = makeSynthScene(SynthSceneKind::Room, 64).scene;
  const Appearance& a = room.appearance;
  const int lightA = idOf(a, "ceiling_light_a"), lightB = idOf(a, "ceiling_light_b");
  // A cube as OBJ, inserted at half size (its faces become one object).
  std::ofstream(dir / "cube.obj") << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                                     "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 1 5 8 4\nf 2 3 7 6\n";
  const SceneDescription e = edited(room, dir, R"({
    "objects": [{"name": "ceiling_light_a", "emission_scale": 0}, {"id": )" + std::to_string(lightB) + R"(, "emission_scale": 2},
                {"id": 0, "albedo": [0.9, 0.1, 0.1], "roughness": 0.2, "specular": 0.8}],
    "add": [{"rectangle": {"center": [2.5, 2.5, 2], "edge_u": [0.5, 0, 0], "edge_v": [0, 0, 0.4]}, "name": "new_light", "emission": [20, 20, 20]},
            {"mesh": "cube.obj", "scale": 0.5, "translate": [1, 0, 1], "name": "box", "albedo": 0.7, "roughness": 0.4}]})");
  const Appearance& b = e.appearance;
  EXPECT_TRUE((b.emission[lightA] == Color::Zero()).all());
  EXPECT_TRUE((b.emission[lightB] == 2 * a.emission[lightB]).all());
  EXPECT_FALSE(b.usesTexture(0));
  EXPECT_TRUE((b.albedoAt(0, Vec2(0.5f, 0.5f)) == Color(0.9f, 0.1f, 0.1f)).all());
  EXPECT_FLOAT_EQ(b.roughness[0], 0.2f);
  EXPECT_FLOAT_EQ(b.specular[0], 0.8f);
  ASSERT_EQ(b.objectCount(), a.objectCount() + 2);
  const int light = a.objectCount(), box = light + 1;
  EXPECT_EQ(b.names[light], "new_light");
  EXPECT_TRUE((b.emission[light] == Color::Constant(20)).all());
  EXPECT_TRUE((b.albedoConstant[box] == Color::Constant(0.7f)).all());
  EXPECT_EQ(e.mesh.triangles.size(), room.mesh.triangles.size() + 2 + 12);
  // The rectangle emits along edge_u x edge_v = -y (down into the room); the cube spans [1, 1.5].
  double area = 0;
  for (size_t f = 0; f < e.mesh.triangles.size(); ++f) {
    if (e.mesh.faceObject[f] == light) {
      EXPECT_NEAR(e.mesh.faceNormal(f).y(), -1.0f, 1e-5f);
      area += e.mesh.faceArea[f];
    }
    if (e.mesh.faceObject[f] == box) {
      for (int k = 0; k < 3; ++k) EXPECT_LE(e.mesh.positions[e.mesh.triangles[f][k]].x(), 1.5f);
    }
  }
  EXPECT_NEAR(area, 0.2, 1e-5);
  EXPECT_EQ(e.mesh.uvs.size(), e.mesh.positions.size());  // the atlas is kept
}

TEST(SceneEdit, BadEditsAreOneLineErrors) {
  const fs::path dir = tmpDir("errors");
  const SceneDescription room = makeSynthScene(SynthSceneKind::Room, 64).scene;
  const std::string unknownName = errorOf(room, dir, R"({"objects": [{"name": "chandelier", "emission_scale": 0}]})");
  EXPECT_NE(unknownName.find("edit.json: objects[0]: no object named 'chandelier'"), std::string::npos) << unknownName;
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 99, "emission_scale": 0}]})").find("no object with id 99"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 1, "emision_scale": 0}]})").find("unknown key 'emision_scale'"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 1, "emission_scale": -1}]})").find("must be >= 0"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 1, "roughness": 2}]})").find("roughness"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"add": [{"name": "x"}]})").find("exactly one of 'rectangle' and 'mesh'"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"add": [{"mesh": "missing.ply"}]})").find("missing.ply"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"add": [{"rectangle": {"center": [0,0,0], "edge_u": [1,0,0], "edge_v": [2,0,0]}}]})")
                .find("span a rectangle"), std::string::npos);
  for (const std::string& msg : {unknownName, errorOf(room, dir, "{\"objects\": 3}")})
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
}
