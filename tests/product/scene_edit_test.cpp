// `relume render --edit`: what each edit does to the scene, one-line errors, and the relight test
// (a reconstruction edited against the ground truth edited the same way, built independently).
#include <gtest/gtest.h>

#include <fstream>

#include "capture/transforms.h"
#include "core/error.h"
#include "io/atomic_file.h"
#include "io/image.h"
#include "io/json.h"
#include "product/fit.h"
#include "product/scene_edit.h"
#include "scenes/synth.h"
#include "render/film.h"
#include "render/lights.h"
#include "support/prepared_capture.h"

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
  const SceneDescription e = edited(room, dir,
                                    R"({
    "objects": [{"name": "ceiling_light_a", "emission_scale": 0}, {"id": )" +
                                        std::to_string(lightB) + R"(, "emission_scale": 2},
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
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 99, "emission_scale": 0}]})").find("no object with id 99"),
            std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 1, "emision_scale": 0}]})").find("unknown key 'emision_scale'"),
            std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 1, "emission_scale": -1}]})").find("must be >= 0"),
            std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"objects": [{"id": 1, "roughness": 2}]})").find("roughness"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"add": [{"name": "x"}]})").find("exactly one of 'rectangle' and 'mesh'"),
            std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"add": [{"mesh": "missing.ply"}]})").find("missing.ply"), std::string::npos);
  EXPECT_NE(errorOf(room, dir, R"({"add": [{"rectangle": {"center": [0,0,0], "edge_u": [1,0,0], "edge_v": [2,0,0]}}]})")
                .find("span a rectangle"),
            std::string::npos);
  for (const std::string& msg : {unknownName, errorOf(room, dir, "{\"objects\": 3}")})
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
}

// ---- Relight: a fitted reconstruction edited with --edit against the ground truth edited by hand.

namespace {

constexpr const char* kRelightEdit = R"({
  "objects": [{"name": "ceiling_light_a", "emission_scale": 0}, {"name": "ceiling_light_b", "emission_scale": 0}, {"name": "sofa", "albedo": [0.1, 0.2, 0.7], "roughness": 0.4}],
  "add": [{"rectangle": {"center": [3.5, 2.6, 1.0], "edge_u": [0.6, 0, 0], "edge_v": [0, 0, 0.5]}, "name": "new_light",
           "emission": [12, 11, 9]},
          {"mesh": "cube.obj", "scale": 0.5, "translate": [2.2, 0, 2.6], "name": "box", "albedo": [0.7, 0.6, 0.2], "roughness": 0.5}]})";

// The same edit written straight into a copy of the truth's files (scene.json objects, mesh.ply
// triangles), without product/scene_edit: one vertex triple per added triangle.
fs::path editTruthByHand(const fs::path& gtDir, const fs::path& out) {
  Json scene = readJson(gtDir / "scene.json");
  MeshData mesh = readPly(gtDir / scene["mesh"].get<std::string>());
  for (Json& o : scene["objects"]) {
    if (o["name"] == "ceiling_light_a" || o["name"] == "ceiling_light_b") o["emission"] = {0, 0, 0};
    if (o["name"] == "sofa") o["albedo"] = {0.1, 0.2, 0.7}, o["roughness"] = 0.4;
  }
  const int newLight = static_cast<int>(scene["objects"].size()), box = newLight + 1;
  auto addTriangle = [&](Vec3 a, Vec3 b, Vec3 c, int object) {
    const int v = static_cast<int>(mesh.positions.size());
    for (const Vec3& p : {a, b, c}) {
      mesh.positions.push_back(p);
      if (!mesh.uvs.empty()) mesh.uvs.push_back(Vec2::Zero());
      if (!mesh.normals.empty()) mesh.normals.push_back((b - a).cross(c - a).normalized());
    }
    mesh.triangles.push_back({v, v + 1, v + 2});
    mesh.faceObject.push_back(object);
  };
  // Rectangle centre (3.5, 2.6, 1.0), 0.6 x 0.5, facing down.
  const Vec3 c(3.5f, 2.6f, 1.0f), u(0.3f, 0, 0), w(0, 0, 0.25f);
  addTriangle(c - u - w, c + u - w, c + u + w, newLight);
  addTriangle(c - u - w, c + u + w, c - u + w, newLight);
  // Cube [0,1]^3 scaled by 0.5, moved to (2.2, 0, 2.6); outward winding.
  auto P = [](int x, int y, int z) { return Vec3(2.2f + 0.5f * x, 0.5f * y, 2.6f + 0.5f * z); };
  const int quads[6][4][3] = {
      {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}},
      {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{1, 1, 0}, {0, 1, 0}, {0, 1, 1}, {1, 1, 1}},
      {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}}};
  for (const auto& q : quads) {
    auto p = [&](int k) { return P(q[k][0], q[k][1], q[k][2]); };
    addTriangle(p(0), p(1), p(2), box);
    addTriangle(p(0), p(2), p(3), box);
  }
  fs::create_directories(out);
  writePly(out / "mesh.ply", mesh);
  fs::copy_file(gtDir / scene["albedo_texture"].get<std::string>(), out / "albedo.exr");
  scene["mesh"] = "mesh.ply";
  scene["albedo_texture"] = "albedo.exr";
  scene["objects"].push_back({{"id", newLight}, {"name", "new_light"}, {"albedo", 0.5}, {"emission", {12, 11, 9}}});
  scene["objects"].push_back({{"id", box}, {"name", "box"}, {"albedo", {0.7, 0.6, 0.2}}, {"roughness", 0.5}});
  writeJson(out / "scene.json", scene);
  return out / "scene.json";
}

// PSNR of sRGB-encoded [0,1]-clamped images over all views (one exposure, as `relume eval`).
double psnr(const std::vector<Image>& a, const std::vector<Image>& b) {
  double se = 0;
  size_t n = 0;
  for (size_t v = 0; v < a.size(); ++v)
    for (size_t i = 0; i < a[v].rgb.size(); ++i, ++n) {
      const double d =
          linearToSrgb(std::clamp(a[v].rgb[i], 0.0f, 1.0f)) - linearToSrgb(std::clamp(b[v].rgb[i], 0.0f, 1.0f));
      se += d * d;
    }
  return 10.0 * std::log10(1.0 / std::max(se / n, 1e-12));
}

std::vector<Image> renderAll(const SceneDescription& s, const std::vector<Camera>& cams) {
  const Scene scene(s.mesh);
  const LightSampler lights(scene, s.appearance);
  RenderOptions ro;
  ro.spp = 64;
  ro.path.maxDepth = 4;
  std::vector<Image> images;
  for (const Camera& c : cams) images.push_back(renderImage(scene, s.appearance, lights, c, ro).color);
  return images;
}

}  // namespace

TEST(SceneEdit, RelightingTheReconstructionMatchesTheEditedTruth) {
  SynthCaptureOptions so;
  so.kind = SynthSceneKind::Room;
  so.frames = 16, so.testFrames = 2, so.width = 64, so.height = 48, so.spp = 8, so.testSpp = 8,
  so.atlasResolution = 256;
  const fs::path dir = preparedCapture("edit_relight", so, 256);
  FitConfig fc;
  fc.batchTexels = 2048, fc.maxDepth = 4, fc.emissionIterations = 80, fc.materialIterations = 20, fc.albedoPasses = 6;
  fc.emissionTextureIterations = 0, fc.checkpointEvery = 1000;
  runFit(dir / "work", fc, false);

  std::ofstream(dir / "cube.obj") << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                                     "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 3 4 8 7\nf 1 5 8 4\nf 2 3 7 6\n";
  std::vector<Camera> cams;
  for (const Frame& f : readTransforms(dir / "capture" / "transforms_test.json").frames) cams.push_back(f.camera);
  const SceneDescription fit = loadSceneFile(dir / "work" / "result" / "scene.json");
  const SceneDescription truth = loadSceneFile(dir / "capture" / "gt" / "scene.json");
  const SceneDescription truthEdited = loadSceneFile(editTruthByHand(dir / "capture" / "gt", dir / "truth_edited"));
  const std::vector<Image> truthEditedViews = renderAll(truthEdited, cams);
  const double reached = psnr(renderAll(fit, cams), renderAll(truth, cams));
  const double relit = psnr(renderAll(edited(fit, dir, kRelightEdit), cams), truthEditedViews);
  const double unedited = psnr(renderAll(fit, cams), truthEditedViews);
  fmt::print(
      "relight: fit vs truth {:.2f} dB; relit vs edited truth {:.2f} dB; unedited fit vs edited truth {:.2f} dB\n",
      reached, relit, unedited);
  // Stated bound: the relit reconstruction agrees with the edited truth to within 2 dB of what
  // the fit reached on the unedited scene, and far better than the unedited reconstruction (measured: 28.2, 28.8
  // and 11.7 dB; seeds 1-4: relit 27.3-28.8 dB; before the unseen painting was excluded from the emitters, one seed in
  // three made it a light and relit at 22-23 dB).
  EXPECT_GT(relit, reached - 2.0) << "fit vs truth " << reached << " dB, relit " << relit << " dB";
  EXPECT_GT(relit, unedited + 8.0) << "unedited fit vs edited truth " << unedited << " dB, relit " << relit << " dB";
}
