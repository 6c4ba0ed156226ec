// How good a reconstruction is. Against held-out photographs: re-render at their cameras and
// compare (PSNR on tone-mapped images at one exposure, MSRE as in the paper). Against a ground
// truth (synthetic captures): albedo MAE/PSNR on texels observed often enough, per-object
// roughness/specular error where highlights were observed, emitter set and emission error.
#pragma once
#include <filesystem>
#include <vector>

#include "io/json.h"
#include "render/film.h"
#include "scene/appearance.h"

namespace relume {

struct ViewComparison {
  double psnr = 0, msre = 0;          // means over frames
  std::vector<double> framePsnr, frameMsre;
  Json toJson() const;
};

// Renders `scene` at every frame of `cameras` and compares with the frames' images (masked
// pixels skipped). Writes the renders (EXR + PNG) into `out` when it is not empty.
ViewComparison compareViews(const SceneDescription& scene, const std::filesystem::path& cameras, const RenderOptions& render,
                            const std::filesystem::path& out = {});

struct TruthOptions {
  int minObservations = 5;           // albedo texels observed at least this often count
  std::vector<uint8_t> highlightObserved;  // per object: roughness/specular count (empty: all)
};
// The options a fit's result asks for: roughness/specular scored on the objects its materials.json
// (beside scene.json) says the frames showed a highlight on; every object when there is none.
TruthOptions truthOptionsFor(const std::filesystem::path& sceneFile);

struct TruthComparison {
  size_t albedoTexels = 0;
  double albedoMae = 0, albedoPsnr = 0;
  // Peers' measures, over the same texels: PSNR of 8-bit sRGB albedo maps and of 8-bit roughness
  // maps (each texel its object's roughness), and the IoU of emitting texels (every covered texel).
  double albedoPsnr8 = 0, roughnessPsnr8 = 0, emissionIou = 0;
  double roughnessMae = 0, specularMae = 0;
  int materialObjects = 0;
  int emittersTrue = 0, emittersFound = 0, emittersCorrect = 0;
  double emissionRelError = 0;       // mean over true emitters found, mean over channels
  Json perObject = Json::array();
  Json toJson() const;
};

// `coverage`: prepare's coverage.exr (observations per texel over the fit's atlas).
// The two meshes must have the same triangles in the same order (the fit's atlas mesh re-uses
// the capture's triangles); the truth may have its own uv layout.
// `truthAlbedo`, when given, receives the true albedo in the fit's atlas layout (for pictures).
TruthComparison compareWithTruth(const SceneDescription& fit, const SceneDescription& truth,
                                 const Image& coverage, const TruthOptions& options,
                                 Image* truthAlbedo = nullptr);

// `relume eval`: re-renders `scene` at the frames of `cameras` into `out`, compares (and with
// `truth`, scored where `coverage` shows enough observations), writes OUT/eval.json, then prints
// the scores on stdout.
struct EvalOptions {
  std::filesystem::path scene, cameras, out, truth, coverage;
  int spp = 64;
};
void runEvaluation(const EvalOptions& o);

}  // namespace relume
