// Radiance and gradient sums cannot overflow float: emission above the bound every reader enforces
// (kMaxEmission) is an input error naming the file and field, and pixel sums are carried in double.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "capture/transforms.h"
#include "core/error.h"
#include "io/json.h"
#include "product/scene_edit.h"
#include "render/film.h"
#include "render/lights.h"
#include "scenes/synth.h"
#include "support/run_relume.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

constexpr int kInputErrorExit = 1;  // src/cli/main.cpp

// A 2-frame 16x16 Cornell box capture in a fresh folder, its ground-truth light's emission set to
// `emission` in gt/scene.json (finite in float, so the number itself is read as valid JSON).
fs::path cornellWithEmission(const std::string& name, double emission) {
  const fs::path dir = fs::temp_directory_path() / ("relume_radiance_bounds_" + name);
  fs::remove_all(dir);
  SynthCaptureOptions so;
  so.kind = SynthSceneKind::Cornell;
  so.out = dir;
  so.frames = 2, so.testFrames = 1, so.width = so.height = 16, so.spp = 1, so.testSpp = 1, so.atlasResolution = 64;
  writeSynthCapture(so);
  Json scene = readJson(dir / "gt" / "scene.json");
  for (Json& o : scene["objects"])
    if (o["emission"][0].get<double>() > 0) o["emission"] = {emission, emission, emission};
  writeJson(dir / "gt" / "scene.json", scene);
  return dir;
}

void expectEmissionRefused(const RelumeRun& run, const fs::path& scene) {
  EXPECT_EQ(run.exitCode, kInputErrorExit) << run.output;
  EXPECT_EQ(run.output.find("internal error"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find(scene.string()), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("'emission"), std::string::npos) << run.output;
}

}  // namespace

// Issue 42: a wall with emission 1e38 rendered +Inf pixels and `relume render` exited 0.
TEST(RadianceBounds, RenderRefusesEmissionBeyondTheBound) {
  const fs::path dir = cornellWithEmission("render", 1e38);
  const fs::path scene = dir / "gt" / "scene.json";
  const RelumeRun run =
      runRelume("render --scene '" + scene.string() + "' --cameras '" + (dir / "transforms.json").string() +
                "' --out '" + (dir / "out").string() + "' --spp 4");
  expectEmissionRefused(run, scene);
  EXPECT_FALSE(fs::exists(dir / "out" / "frame_0000.exr"));
  fs::remove_all(dir);
}

// Issue 42: emission 1e30 gave NaN rows in gradcheck's table.
TEST(RadianceBounds, GradcheckRefusesEmissionBeyondTheBound) {
  const fs::path dir = cornellWithEmission("gradcheck", 1e30);
  const fs::path scene = dir / "gt" / "scene.json";
  const RelumeRun run = runRelume("gradcheck --scene '" + scene.string() + "' --cameras '" +
                                  (dir / "transforms.json").string() + "' --param all --rays 256 --batches 2");
  expectEmissionRefused(run, scene);
  EXPECT_EQ(run.output.find("nan"), std::string::npos) << run.output;
  fs::remove_all(dir);
}

// The film sums a pixel's samples in double: emission near float's largest value (set directly,
// past every reader) seen straight by the camera gives finite pixels (the mean of finite
// radiances), where a float sum of 8 samples of 1e38 was +Inf.
TEST(RadianceBounds, PixelSumsDoNotOverflowFloat) {
  SceneDescription desc = makeSynthScene(SynthSceneKind::Cornell, 64).scene;
  int light = 0;
  while (!desc.appearance.isEmissive(light)) ++light;
  desc.appearance.emission[light] = Color::Constant(1e38f);
  // A camera 0.3 m below the light's centre, looking up at its front (it faces down).
  Vec3 centre = Vec3::Zero();
  int corners = 0;
  for (size_t f = 0; f < desc.mesh.triangles.size(); ++f)
    if (desc.mesh.faceObject[f] == light)
      for (int k = 0; k < 3; ++k) centre += desc.mesh.positions[desc.mesh.triangles[f][k]], ++corners;
  Camera camera;
  camera.width = camera.height = 16, camera.fx = camera.fy = 8, camera.cx = camera.cy = 8;
  camera.position = centre / corners - Vec3(0, 0.3f, 0);
  camera.rotation.col(0) = Vec3(1, 0, 0), camera.rotation.col(1) = Vec3(0, 0, -1),
  camera.rotation.col(2) = Vec3(0, 1, 0);
  const Scene scene(desc.mesh);
  const LightSampler lights(scene, desc.appearance);
  RenderOptions ro;
  ro.spp = 8;
  const RenderResult r = renderImage(scene, desc.appearance, lights, camera, ro);
  size_t nonFinite = 0, atLight = 0;
  for (float v : r.color.rgb) nonFinite += !std::isfinite(v), atLight += v > 1e37f;
  EXPECT_EQ(nonFinite, 0u);
  EXPECT_GT(atLight, 0u);  // the light's pixels carry its radiance, finite
}

// An edit's emission_scale multiplies an emission already at most the bound: the product is checked.
TEST(RadianceBounds, EditEmissionScaleBeyondTheBoundIsRefused) {
  const fs::path dir = fs::temp_directory_path() / "relume_radiance_bounds_edit";
  fs::remove_all(dir);
  fs::create_directories(dir);
  SceneDescription desc = makeSynthScene(SynthSceneKind::Cornell, 64).scene;
  int light = 0;
  while (!desc.appearance.isEmissive(light)) ++light;
  writeJson(dir / "edit.json", Json{{"objects", {{{"id", light}, {"emission_scale", 1e30}}}}});
  try {
    applySceneEdit(desc, dir / "edit.json");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'emission_scale'"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

// Radiance is pixel / exposure: an exposure of 1e-30 would turn a pixel of 1 into 1e30.
TEST(RadianceBounds, ExposureBeyondTheBoundIsRefused) {
  const fs::path dir = fs::temp_directory_path() / "relume_radiance_bounds_exposure";
  fs::remove_all(dir);
  Frame f;
  f.camera.width = f.camera.height = 4, f.camera.fx = f.camera.fy = 4, f.camera.cx = f.camera.cy = 2;
  f.image = dir / "a.exr";
  writeTransforms(dir / "transforms.json", {f});
  Json t = readJson(dir / "transforms.json");
  t["frames"][0]["exposure"] = 1e-30;
  writeJson(dir / "transforms.json", t);
  try {
    readTransforms(dir / "transforms.json");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'exposure'"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
