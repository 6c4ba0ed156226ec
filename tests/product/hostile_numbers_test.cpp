// Numbers that would silently become other numbers: a fit config's integers are read in the type
// they are used in (an integer that does not fit an int, a negative seed), and an edit's mesh
// scale may not put vertices beyond the world's bound.
#include <gtest/gtest.h>

#include <string>

#include <filesystem>

#include "core/error.h"
#include "io/json.h"
#include "product/fit_config.h"
#include "product/scene_edit.h"
#include "scenes/synth.h"

using namespace relume;

TEST(FitConfigNumbers, OutOfTypeNumbersAreRefused) {
  for (const auto& [json, key] : std::vector<std::pair<std::string, std::string>>{
           {R"({"batch_texels": 4294967297})", "batch_texels"},  // would wrap onto 1
           {R"({"seed": -1})", "seed"}}) {
    try {
      FitConfig::fromJson(Json::parse(json), "config.json", FitConfig{});
      ADD_FAILURE() << json << ": no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("'" + key + "'"), std::string::npos) << e.what();
    }
  }
}

TEST(EditNumbers, MeshScaleBeyondTheWorldIsRefused) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "relume_hostile_numbers_edit";
  fs::remove_all(dir);
  MeshData tri;
  tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri.triangles = {{0, 1, 2}};
  writePly(dir / "tri.ply", tri);  // creates dir
  writeJson(dir / "edit.json", Json{{"add", {{{"mesh", "tri.ply"}, {"scale", 1e10}}}}});
  SceneDescription desc = makeSynthScene(SynthSceneKind::Cornell, 64).scene;
  try {
    applySceneEdit(desc, dir / "edit.json");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'scale' and 'translate' put vertex 1"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}
