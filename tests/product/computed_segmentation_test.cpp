// Known answer: the room captured without a segmentation (a mesh with no object ids, as most
// scanners give it). Prepare computes one from the mesh and the frames; the fit then finds the
// ceiling panels as it does with the true segmentation.
#include <gtest/gtest.h>

#include <map>

#include "io/json.h"
#include "product/evaluate.h"
#include "product/fit.h"
#include "scene/appearance.h"
#include "scenes/imperfections.h"
#include "support/prepared_capture.h"
#include "support/small_fit_config.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// No computed object straddles two true ones (by area: at most 1% of it elsewhere), and every
// true light is exactly one computed object.
void expectCleanSegmentation(const TriangleMesh& fitted, const SceneDescription& truth) {
  ASSERT_EQ(fitted.triangles.size(), truth.mesh.triangles.size());
  EXPECT_GE(fitted.objectCount, truth.mesh.objectCount);
  std::map<std::pair<int, int>, double> overlap;
  std::vector<double> fittedArea(fitted.objectCount, 0.0);
  for (size_t f = 0; f < fitted.triangles.size(); ++f) {
    const double a = truth.mesh.faceArea[f];
    overlap[{fitted.faceObject[f], truth.mesh.faceObject[f]}] += a;
    fittedArea[fitted.faceObject[f]] += a;
  }
  for (const auto& [ids, area] : overlap) {
    if (area >= 0.5 * fittedArea[ids.first]) continue;
    EXPECT_LT(area, 0.01 * fittedArea[ids.first])
        << "computed object " << ids.first << " straddles true object " << truth.appearance.names[ids.second];
  }
  for (int t = 0; t < truth.mesh.objectCount; ++t) {
    if (!truth.appearance.isEmissive(t)) continue;
    int parts = 0;
    for (const auto& [ids, area] : overlap)
      if (ids.second == t) {
        ++parts;
        EXPECT_NEAR(area, fittedArea[ids.first], 1e-9 * area) << truth.appearance.names[t] << " shares its object";
      }
    EXPECT_EQ(parts, 1) << truth.appearance.names[t] << " is split";
  }
}

}  // namespace

TEST(ComputedSegmentation, TheRoomWithoutObjectIdsIsSegmentedCleanlyAndItsLightsFound) {
  const fs::path dir = preparedCapture("computed_segmentation", room256("segmentation=none"), 256);
  ASSERT_TRUE(readJson(dir / "work" / "prepare.json")["phases"].contains("segmentation"));
  const SceneDescription truth = loadSceneFile(dir / "capture" / "gt" / "scene.json");
  const TriangleMesh fitted = loadMesh(dir / "work" / "atlas_mesh.ply");
  expectCleanSegmentation(fitted, truth);

  FitConfig c = smallFitConfig();
  c.checkpointEvery = 1000;
  runFit(dir / "work", c, false);
  const SceneDescription fit = loadSceneFile(dir / "work" / "result" / "scene.json");
  const TruthComparison score = compareWithTruth(fit, truth, readImage(dir / "work" / "coverage.exr"), {});
  EXPECT_EQ(score.emittersTrue, 2);
  EXPECT_EQ(score.emittersCorrect, 2);
  EXPECT_EQ(score.emittersFound, 2);
  EXPECT_LT(score.emissionRelError, 0.15);
  std::printf("computed segmentation: %d objects for %d; albedo MAE %.4f, emission error %.1f%%\n",
              fitted.objectCount, truth.mesh.objectCount, score.albedoMae, 100 * score.emissionRelError);
}

// 8-bit frames bracketed -1.5/0/+1.5 EV store the panels at 255 in every frame: their faces show
// only floors, which differ with the frames that saw each face. Each panel is still one object,
// apart from the ceiling. The mesh's own ids, when given, are kept.
TEST(ComputedSegmentation, PanelsSeenOnlyClippedStayWholeAndGivenIdsAreKept) {
  const fs::path dir = preparedCapture("computed_segmentation_ldr",
                                       room256("bracket=-1.5,0,1.5;ldr=8;segmentation=none"), 256);
  const SceneDescription truth = loadSceneFile(dir / "capture" / "gt" / "scene.json");
  expectCleanSegmentation(loadMesh(dir / "work" / "atlas_mesh.ply"), truth);

  const fs::path given = preparedCapture("computed_segmentation_given", room256("ldr=8"), 256);
  EXPECT_FALSE(readJson(given / "work" / "prepare.json")["phases"].contains("segmentation"));
  const TriangleMesh kept = loadMesh(given / "work" / "atlas_mesh.ply");
  EXPECT_EQ(kept.objectCount, truth.mesh.objectCount);
  EXPECT_EQ(kept.faceObject, truth.mesh.faceObject);
}
