// How good a reconstruction is. Against held-out photographs: re-render at their cameras and
// compare (PSNR on tone-mapped images at one exposure, MSRE as in the paper). Against a ground
// truth (synthetic captures): albedo MAE/PSNR on texels observed often enough, per-object
// roughness/specular error where highlights were observed, emitter set and emission error.
#pragma once
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "capture/transforms.h"
#include "io/image.h"
#include "io/json.h"
#include "render/film.h"
#include "scene/appearance.h"
#include "scene/texel_map.h"

namespace relume {

struct ViewComparison {
  double psnr = 0, msre = 0;  // means over frames
  std::vector<double> framePsnr, frameMsre;
  Json toJson() const;
};

// One image against a reference: PSNR on tone-mapped values ([0,1]-clamped, sRGB) and MSRE,
// pixels the reference masks (negative) skipped. Throws when every pixel is masked (`what` names
// the reference in the message).
struct ImageScore {
  double psnr = 0, msre = 0;
};
ImageScore scoreImage(const Image& estimate, const Image& reference, const std::string& what);

// A render made of two independent halves (seeds 2 * seed and 2 * seed + 1, half the samples
// each), so that it carries an estimate of its own Monte Carlo noise.
struct SplitRender {
  Image mean;   // the render: both halves' samples
  Image noise;  // the halves' difference, scaled to have the variance of `mean`'s noise
};
SplitRender renderSplit(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                        const Camera& camera, const RenderOptions& render);

// What separates a re-render from what it should show, with the Monte Carlo noise that is part
// of it, per block x block pixels: the signed difference and its noise are averaged over each
// block before their magnitudes are taken, so the noise falls by `block` while errors smooth at
// that scale (an albedo, a light, a material off) stay. Pixels the reference masks (negative) are
// left out; a block with none left is 0 in both images and out of the means.
struct ViewError {
  Image error, noise;  // |difference| and |its noise|, a pixel per block
  double errorMean = 0, noiseMean = 0, errorRms = 0, noiseRms = 0;
  double referenceMean = 0;  // the reference's mean over the same pixels: the scale of the others
  size_t samples = 0;        // block channels counted
  // The RMS of the difference without its noise: sqrt(errorRms^2 - noiseRms^2), as the noise is
  // independent of what the two images differ by (0 when the noise explains it all).
  double beyondNoiseRms() const;
};
// The fitted and the true scene rendered with the same options, seed included (renderSplit): where
// they agree their noise is the same and cancels, so |fit - truth| is the reconstruction's error;
// what noise remains (paths the two scenes scatter differently) is measured from the halves.
// `reference` (the frame) only masks pixels.
ViewError errorAgainstTruth(const SplitRender& fit, const SplitRender& truth, const Image& reference, int block = 1);
// A re-render against a photograph: |render - photo| and the re-render's own noise (the photo's
// is unknown, so not counted).
ViewError errorAgainstPhoto(const SplitRender& render, const Image& photo, int block = 1);

// Renders `scene` at every frame of `cameras` and compares with the frames' images (masked
// pixels skipped). Writes the renders (EXR + PNG) into `out` when it is not empty.
ViewComparison compareViews(const SceneDescription& scene, const std::filesystem::path& cameras,
                            const RenderOptions& render, const std::filesystem::path& out = {});

struct TruthOptions {
  int minObservations = 5;                 // albedo texels observed at least this often count
  std::vector<uint8_t> highlightObserved;  // per object: roughness/specular count (empty: all)
  std::optional<Image> albedoStandardError;  // the fit's, per texel of its albedo: scored for calibration
};
// The options a fit's result asks for: roughness/specular scored on the objects its materials.json
// (beside scene.json) says the frames showed a highlight on; every object when there is none; the
// albedo's standard errors scored when albedo_stderr.exr is beside it.
TruthOptions truthOptionsFor(const std::filesystem::path& sceneFile);

struct TruthComparison {
  size_t albedoTexels = 0;
  double albedoMae = 0, albedoPsnr = 0;
  double albedoErrorRms() const { return std::pow(10.0, -albedoPsnr / 20); }  // PSNR's peak is 1
  // With the fit's standard errors, over the same texels and channels: their RMS (against the
  // error's, from albedoPsnr) and the fraction of errors within two of them (0.95 if honest and
  // unbiased; bias the errors do not count lowers it).
  double albedoStandardErrorRms = -1, albedoWithinTwoStandardErrors = -1;
  // Peers' measures, over the same texels: PSNR of 8-bit sRGB albedo maps and of 8-bit roughness
  // maps (each texel its object's roughness), and the IoU of emitting texels (every covered texel).
  double albedoPsnr8 = 0, roughnessPsnr8 = 0, emissionIou = 0;
  // Roughness and specular against the truth's: over the objects whose materials the fit took from
  // observed highlights (`materialObjects`), and over every object that is no light in the truth
  // (`opaqueObjects`), those without a highlight included.
  double roughnessMae = 0, specularMae = 0;
  int materialObjects = 0;
  double roughnessMaeAll = 0, specularMaeAll = 0;
  int opaqueObjects = 0;
  int emittersTrue = 0, emittersFound = 0, emittersCorrect = 0;
  double emissionRelError = 0;  // mean over true emitters found, mean over channels
  Json perObject = Json::array();
  Json toJson() const;
};

// Why `fit`'s triangles are not `truth`'s (their count, or a triangle moved by more than half its
// size; vertices moved by a scan's noise are the same triangles); "" when they are.
std::string differentTriangles(const TriangleMesh& fit, const TriangleMesh& truth);

// Where covered texel t of `map` (an atlas of `fitMesh`) lies in the truth's uv layout (0 when the
// truth has none) and in the fit's; the meshes have the same triangles.
struct TexelUvs {
  Vec2 truth, fit;
};
TexelUvs texelUvs(const TriangleMesh& fitMesh, const TriangleMesh& truthMesh, const TexelMap& map, size_t t);
// The true albedo at every covered texel of a res^2 atlas of `fitMesh` (0 elsewhere); throws
// when the meshes' triangles differ.
Image truthAlbedoInAtlas(const TriangleMesh& fitMesh, const SceneDescription& truth, int res);

// `coverage`: prepare's coverage.exr (observations per texel over the fit's atlas).
// The two meshes must have the same triangles in the same order (the fit's atlas mesh re-uses
// the capture's triangles); the truth may have its own uv layout.
// `truthAlbedo`, when given, receives the true albedo in the fit's atlas layout (for pictures).
TruthComparison compareWithTruth(const SceneDescription& fit, const SceneDescription& truth, const Image& coverage,
                                 const TruthOptions& options, Image* truthAlbedo = nullptr);

// The albedo as the held-out views show it, pixel by pixel: at each pixel's centre, the fit's albedo
// where the ray meets the fit's mesh against the reference: the frame's albedo pass when it has one
// (Frame::albedo, what the renderer that made the frames shaded with), else the truth's albedo where
// the ray meets the truth's mesh. The meshes may differ (a displaced or incomplete scan). A pixel
// counts when one object is seen there and in its 8 neighbours (an edge mixes objects, and a mesh off
// by a few millimetres moves them), that object is not a light, with a truth both meshes meet the ray
// within 2 cm (or 2%) of each other (not where one lacks an object), and, with `coverage`, the fit's
// texel there was observed at least `minObservations` times. Objects are the truth's when `truth` is
// given, else the fit's. This is the measure a capture with an albedo pass is judged by.
struct AlbedoViewComparison {
  size_t pixels = 0;
  double mae = 0, psnr = 0;  // over counted pixels and channels; PSNR's peak is 1
  Json perObject = Json::array();  // per object with counted pixels: pixels, MAE, mean signed error
  Json toJson() const;
};
// Throws relume::Error when a view has neither an albedo pass nor a truth, or a pass that is not the
// frame's size. Writes albedo_<frame>.png and albedo_reference_<frame>.png (counted pixels; others
// black) into `out` when it is not empty.
AlbedoViewComparison compareAlbedoViews(const SceneDescription& fit, const SceneDescription* truth,
                                        const std::vector<Frame>& views, const Image* coverage, int minObservations,
                                        const std::filesystem::path& out = {});

// `relume eval`: re-renders `scene` at the frames of `cameras` into `out`, compares (and with
// `truth`, scored where `coverage` shows enough observations), writes OUT/eval.json, then prints
// the scores on stdout.
struct EvalOptions {
  std::filesystem::path scene, cameras, out, truth, coverage;
  int spp = 64;
};
void runEvaluation(const EvalOptions& o);

}  // namespace relume
