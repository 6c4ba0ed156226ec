// Peers' truth measures of `relume eval`: 8-bit albedo and roughness map PSNR, emission IoU; re-renders
// against a truth with the same random numbers, and their noise estimates.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "core/rng.h"
#include "io/image.h"
#include "io/json.h"
#include "product/evaluate.h"
#include "render/lights.h"
#include "scenes/synth.h"

using namespace relume;

namespace {
struct Pair {
  SceneDescription truth, fit;
  Image coverage;  // every texel observed 10 times
};
Pair roomPair() {
  Pair p{makeSynthScene(SynthSceneKind::Room, 64).scene, makeSynthScene(SynthSceneKind::Room, 64).scene, Image(64, 64)};
  std::fill(p.coverage.rgb.begin(), p.coverage.rgb.end(), 10.0f);
  return p;
}
int idOf(const Appearance& a, const std::string& name) {
  return static_cast<int>(std::find(a.names.begin(), a.names.end(), name) - a.names.begin());
}
}  // namespace

TEST(Evaluate, PeersMeasuresAreExactOnTheTruthAndFallWithErrors) {
  Pair p = roomPair();
  const TruthComparison same = compareWithTruth(p.fit, p.truth, p.coverage, {});
  EXPECT_GT(same.albedoTexels, 500u);
  EXPECT_NEAR(same.albedoPsnr8, 120.0, 1e-9);  // identical maps: the 1e-12 floor of the MSE
  EXPECT_NEAR(same.roughnessPsnr8, 120.0, 1e-9);
  EXPECT_DOUBLE_EQ(same.emissionIou, 1.0);

  // Every roughness off by 0.2 (= 51 steps of 8 bits): PSNR 20 log10(255 / 51) on every texel.
  Appearance& a = p.fit.appearance;
  for (float& r : a.roughness) r = r <= 0.8f ? r + 0.2f : r - 0.2f;
  // Darker albedo everywhere: 8-bit PSNR drops far below the identical maps'.
  for (float& v : a.albedo.rgb) v *= 0.5f;
  // One of the two ceiling lights off: the emitting texels of the other are the intersection.
  a.emission[idOf(a, "ceiling_light_b")] = Color::Zero();
  const TruthComparison off = compareWithTruth(p.fit, p.truth, p.coverage, {});
  EXPECT_NEAR(off.roughnessPsnr8, 20.0 * std::log10(255.0 / 51.0), 1e-6);
  EXPECT_LT(off.albedoPsnr8, 25.0);
  EXPECT_GT(off.emissionIou, 0.2);
  EXPECT_LT(off.emissionIou, 0.8);
}

// Roughness and specular are scored over every object that is no light, and apart over those whose
// materials the fit took from observed highlights: a fit wrong only where it saw no highlight
// scores 0 on the second and not on the first.
TEST(Evaluate, MaterialsAreScoredOnEveryObjectThatIsNoLight) {
  Pair p = roomPair();
  Appearance& a = p.fit.appearance;
  const int table = idOf(a, "table"), walls = idOf(a, "walls");
  a.roughness[walls] += 0.3f, a.specular[walls] -= 0.2f;
  TruthOptions options;
  options.highlightObserved.assign(a.objectCount(), 0);
  options.highlightObserved[table] = 1;
  const TruthComparison c = compareWithTruth(p.fit, p.truth, p.coverage, options);
  const int lights = static_cast<int>(std::count_if(a.emission.begin(), a.emission.end(),
                                                    [](const Color& e) { return e.maxCoeff() > 0; }));
  ASSERT_EQ(lights, 2);
  EXPECT_EQ(c.materialObjects, 1);
  EXPECT_EQ(c.roughnessMae, 0.0);
  EXPECT_EQ(c.specularMae, 0.0);
  EXPECT_EQ(c.opaqueObjects, a.objectCount() - lights);
  EXPECT_NEAR(c.roughnessMaeAll, 0.3 / c.opaqueObjects, 1e-6);
  EXPECT_NEAR(c.specularMaeAll, 0.2 / c.opaqueObjects, 1e-6);
  EXPECT_NEAR(c.toJson()["roughness_mae_all"].get<double>(), c.roughnessMaeAll, 1e-12);
}

// A fit on other objects than the truth's (a computed segmentation) is scored per true object over
// its faces: materials weighted by area, a light found where the fit emits over half of it, and
// the fit's lights on true reflectors counted as found but not correct.
TEST(Evaluate, TrueObjectsAreComparedWithTheFitsObjectsOverTheirFaces) {
  Pair p = roomPair();
  TriangleMesh& fm = p.fit.mesh;
  Appearance& a = p.fit.appearance;
  const int floor = idOf(a, "floor"), rug = idOf(a, "rug"), ceiling = idOf(a, "ceiling"),
            lightA = idOf(a, "ceiling_light_a"), lightB = idOf(a, "ceiling_light_b"), cube = idOf(a, "cube");
  // Every other floor face goes to the fit's rug, whose roughness differs.
  a.roughness[floor] = 0.2f, a.roughness[rug] = 0.6f;
  double floorArea = 0, movedArea = 0;
  bool flip = false;
  for (size_t f = 0; f < fm.triangles.size(); ++f)
    if (fm.faceObject[f] == floor) {
      floorArea += fm.faceArea[f];
      if ((flip = !flip)) fm.faceObject[f] = rug, movedArea += fm.faceArea[f];
    }
  // Light a keeps a quarter of its faces; light b three quarters (the rest go to the ceiling).
  int k = 0;
  for (size_t f = 0; f < fm.triangles.size(); ++f) {
    if (fm.faceObject[f] == lightA && k++ % 4 != 0) fm.faceObject[f] = ceiling;
    else if (fm.faceObject[f] == lightB && k++ % 4 == 0) fm.faceObject[f] = ceiling;
  }
  a.emission[cube] = Color::Constant(2.0f);  // a false light
  const TruthComparison c = compareWithTruth(p.fit, p.truth, p.coverage, {});
  for (const Json& row : c.perObject)
    if (row["name"] == "floor") {
      EXPECT_EQ(row["fit_objects"], 2);
      const double expected = (0.2 * (floorArea - movedArea) + 0.6 * movedArea) / floorArea;
      EXPECT_NEAR(row["roughness"][0].get<double>(), expected, 1e-5);
    } else if (row["name"] == "ceiling_light_a") {
      EXPECT_FALSE(row["emitter"][0].get<bool>());
    } else if (row["name"] == "ceiling_light_b") {
      EXPECT_TRUE(row["emitter"][0].get<bool>());
      EXPECT_EQ(row["fit_objects"], 2);
    }
  EXPECT_EQ(c.emittersTrue, 2);
  EXPECT_EQ(c.emittersCorrect, 1);
  EXPECT_EQ(c.emittersFound, 2);  // light b, and the cube
}

namespace {
std::vector<Frame> roomViews() {
  std::vector<Frame> views;
  for (const Camera& c : synthCameraPath(SynthSceneKind::Room, 3, 48, 36, 0.25)) {
    Frame f;
    f.camera = c;
    views.push_back(f);
  }
  return views;
}
}  // namespace

// Albedo in the views: exact on the truth, an albedo off by 0.1 is off by 0.1 in every counted pixel,
// and a displaced mesh is compared where its rays land (the texel measure needs the same triangles).
TEST(Evaluate, AlbedoInTheViewsIsComparedPixelByPixelOnObjectsInteriors) {
  Pair p = roomPair();
  const std::vector<Frame> views = roomViews();
  const AlbedoViewComparison same = compareAlbedoViews(p.fit, &p.truth, views, &p.coverage, 5);
  ASSERT_GT(same.pixels, 1000u);
  EXPECT_EQ(same.mae, 0.0);
  EXPECT_LT(same.pixels, 3u * 46 * 34);  // edges and the lights are left out
  for (const Json& row : same.perObject)
    EXPECT_EQ(row["name"].get<std::string>().rfind("ceiling_light", 0), std::string::npos);

  for (float& v : p.fit.appearance.albedo.rgb) v += 0.1f;
  const AlbedoViewComparison brighter = compareAlbedoViews(p.fit, &p.truth, views, &p.coverage, 5);
  EXPECT_EQ(brighter.pixels, same.pixels);
  EXPECT_NEAR(brighter.mae, 0.1, 1e-4);
  EXPECT_NEAR(brighter.psnr, 20.0, 1e-2);
  for (const Json& row : brighter.perObject) EXPECT_NEAR(row["bias"].get<double>(), 0.1, 1e-4) << row.dump();

  // Unobserved texels are not counted.
  Image unseen(64, 64);
  EXPECT_EQ(compareAlbedoViews(p.fit, &p.truth, views, &unseen, 5).pixels, 0u);
}

// A capture's albedo pass is the reference where a frame has one: with no truth, the fit's objects
// mask it; a pass of another size, or a view with neither pass nor truth, is an error.
TEST(Evaluate, AlbedoPassesAreTheReferenceWhereFramesHaveThem) {
  Pair p = roomPair();
  std::fill(p.fit.appearance.albedo.rgb.begin(), p.fit.appearance.albedo.rgb.end(), 0.5f);
  std::vector<Frame> views = roomViews();
  const std::filesystem::path dir = testing::TempDir() + "albedo_passes";
  std::filesystem::create_directories(dir);
  for (size_t k = 0; k < views.size(); ++k) {
    Image pass(views[k].camera.width, views[k].camera.height);
    std::fill(pass.rgb.begin(), pass.rgb.end(), k == 0 ? 0.7f : 0.5f);
    views[k].albedo = dir / fmt::format("albedo_{}.exr", k);
    writeExr(views[k].albedo, pass);
  }
  const AlbedoViewComparison withTruth = compareAlbedoViews(p.fit, &p.truth, views, &p.coverage, 5);
  const AlbedoViewComparison fitObjects = compareAlbedoViews(p.fit, nullptr, views, &p.coverage, 5);
  for (const AlbedoViewComparison& c : {withTruth, fitObjects}) {
    ASSERT_GT(c.pixels, 1000u);
    EXPECT_GT(c.mae, 0.01);  // the first view's pass is 0.2 brighter than the fit
    EXPECT_LT(c.mae, 0.2 * 0.5);
  }
  views.erase(views.begin());
  EXPECT_LT(compareAlbedoViews(p.fit, nullptr, views, &p.coverage, 5).mae, 1e-6);  // bilinear rounding
  views[0].albedo.clear();
  EXPECT_THROW(compareAlbedoViews(p.fit, nullptr, views, &p.coverage, 5), Error);
  writeExr(views[1].albedo, Image(8, 8));
  EXPECT_THROW(compareAlbedoViews(p.fit, &p.truth, views, &p.coverage, 5), Error);
}

TEST(Evaluate, ADisplacedMeshIsScoredAndADifferentOneRefused) {
  Pair p = roomPair();
  TriangleMesh& fm = p.fit.mesh;
  Pcg32 rng(7);
  for (Vec3& v : fm.positions)  // a scan's noise: up to 5 mm in each coordinate
    v += 0.005f * Vec3(2 * rng.next1D() - 1, 2 * rng.next1D() - 1, 2 * rng.next1D() - 1);
  const TruthComparison texels = compareWithTruth(p.fit, p.truth, p.coverage, {});
  EXPECT_LT(texels.albedoMae, 1e-6);  // same triangles: each texel against the truth at its own point
  const AlbedoViewComparison views = compareAlbedoViews(p.fit, &p.truth, roomViews(), &p.coverage, 5);
  EXPECT_GT(views.pixels, 1000u);
  EXPECT_LT(views.mae, 0.01);  // the striped wallpaper's stripes move by the noise: a little error
  EXPECT_GT(views.mae, 0.0);

  std::rotate(fm.triangles.begin(), fm.triangles.begin() + 1, fm.triangles.end());  // other triangles
  EXPECT_THROW(compareWithTruth(p.fit, p.truth, p.coverage, {}), Error);
}

// Where the fit's mesh lacks an object, the views compare nothing: its surfaces behind are not the
// object's.
TEST(Evaluate, PixelsWhereTheFitsMeshLacksAnObjectAreLeftOut) {
  Pair p = roomPair();
  const std::vector<Frame> views = roomViews();
  const AlbedoViewComparison whole = compareAlbedoViews(p.fit, &p.truth, views, nullptr, 5);
  TriangleMesh& fm = p.fit.mesh;
  const int shelf = idOf(p.fit.appearance, "shelf");
  size_t kept = 0;
  for (size_t f = 0; f < fm.triangles.size(); ++f)
    if (fm.faceObject[f] != shelf) fm.triangles[kept] = fm.triangles[f], fm.faceObject[kept] = fm.faceObject[f], ++kept;
  fm.triangles.resize(kept), fm.faceObject.resize(kept);
  const AlbedoViewComparison without = compareAlbedoViews(p.fit, &p.truth, views, nullptr, 5);
  EXPECT_LT(without.pixels, whole.pixels) << whole.perObject.dump();
  EXPECT_EQ(without.mae, 0.0);
  for (const Json& row : without.perObject) EXPECT_NE(row["name"], "shelf");
}

namespace {
struct Rendered {
  SceneDescription desc;
  Scene scene;
  LightSampler lights;
  explicit Rendered(SceneDescription d) : desc(std::move(d)), scene(desc.mesh), lights(scene, desc.appearance) {}
  SplitRender render(const Camera& camera, int spp, uint64_t seed) const {
    RenderOptions ro;
    ro.spp = spp, ro.seed = seed;
    return renderSplit(scene, desc.appearance, lights, camera, ro);
  }
};
Camera cornellCamera() { return synthCameraPath(SynthSceneKind::Cornell, 1, 32, 24, 0.0)[0]; }
}  // namespace

TEST(Evaluate, SameRandomNumbersCancelTheNoiseOfTwoCopiesOfAScene) {
  const Rendered fit(makeSynthScene(SynthSceneKind::Cornell, 64).scene),
      truth(makeSynthScene(SynthSceneKind::Cornell, 64).scene);
  const SplitRender a = fit.render(cornellCamera(), 4, 7), b = truth.render(cornellCamera(), 4, 7);
  const ViewError e = errorAgainstTruth(a, b, b.mean);
  EXPECT_EQ(e.samples, b.mean.rgb.size());
  for (size_t i = 0; i < e.error.rgb.size(); ++i) {
    ASSERT_EQ(e.error.rgb[i], 0.0f) << i;
    ASSERT_EQ(e.noise.rgb[i], 0.0f) << i;
  }
  EXPECT_EQ(e.errorRms, 0.0);
  // Not for lack of noise: the render's halves differ, and so do other random numbers.
  EXPECT_GT(errorAgainstPhoto(a, b.mean).noiseMean, 0.0);
  EXPECT_GT(errorAgainstTruth(a, truth.render(cornellCamera(), 4, 8), b.mean).errorMean, 0.0);
}

TEST(Evaluate, TheNoiseEstimateExplainsIndependentRendersAndNotAReconstructionError) {
  const Camera camera = cornellCamera();
  const Rendered truth(makeSynthScene(SynthSceneKind::Cornell, 64).scene);
  // The same scene with other random numbers: the difference is all noise, and the halves say how much.
  const ViewError noise =
      errorAgainstTruth(truth.render(camera, 8, 1), truth.render(camera, 8, 2), truth.render(camera, 8, 1).mean);
  EXPECT_GT(noise.noiseRms, 0.0);
  EXPECT_GT(noise.errorRms / noise.noiseRms, 0.7);
  EXPECT_LT(noise.errorRms / noise.noiseRms, 1.4);
  // The walls 20% darker, same random numbers: the error is the reconstruction's, the noise left in it small.
  SceneDescription darker = makeSynthScene(SynthSceneKind::Cornell, 64).scene;
  for (float& v : darker.appearance.albedo.rgb) v *= 0.8f;
  const Rendered fit(std::move(darker));
  const SplitRender t = truth.render(camera, 8, 1);
  const ViewError e = errorAgainstTruth(fit.render(camera, 8, 1), t, t.mean);
  EXPECT_GT(e.errorMean, 0.05 * e.referenceMean);
  EXPECT_LT(e.noiseRms, 0.25 * e.errorRms);
  EXPECT_GT(e.beyondNoiseRms(), 0.9 * e.errorRms);
}

TEST(Evaluate, BlocksAverageTheNoiseDownAndKeepSmoothErrors) {
  const Rendered truth(makeSynthScene(SynthSceneKind::Cornell, 64).scene);
  const SplitRender r = truth.render(cornellCamera(), 4, 3);
  Image photo = r.mean;  // 0.05 brighter everywhere, the first pixel masked
  for (float& v : photo.rgb) v += 0.05f;
  for (int k = 0; k < 3; ++k) photo.rgb[k] = -1.0f;
  const ViewError pixels = errorAgainstPhoto(r, photo), blocks = errorAgainstPhoto(r, photo, 4),
                  odd = errorAgainstPhoto(r, photo, 5);
  EXPECT_EQ(pixels.samples, 32u * 24 * 3 - 3);
  EXPECT_EQ(blocks.error.width, 8);
  EXPECT_EQ(blocks.error.height, 6);
  EXPECT_EQ(odd.error.width, 7);  // partial blocks at the edges
  EXPECT_EQ(odd.error.height, 5);
  EXPECT_EQ(blocks.samples, 8u * 6 * 3);
  for (const ViewError* v : {&pixels, &blocks, &odd}) {
    EXPECT_NEAR(v->errorMean, 0.05, 1e-5);
    EXPECT_NEAR(v->errorRms, 0.05, 1e-5);
  }
  // Independent pixels: the noise of a 4x4 block's mean is a quarter of a pixel's.
  EXPECT_GT(pixels.noiseRms, 0.0);
  EXPECT_GT(blocks.noiseRms / pixels.noiseRms, 0.15);
  EXPECT_LT(blocks.noiseRms / pixels.noiseRms, 0.4);
  EXPECT_THROW(errorAgainstPhoto(r, photo, 0), Error);
}

TEST(Evaluate, MaskedPixelsAreLeftOutOfScoresAndErrors) {
  Image reference(2, 1), estimate(2, 1);
  std::fill(reference.rgb.begin(), reference.rgb.end(), 0.5f);
  std::fill(estimate.rgb.begin(), estimate.rgb.end(), 0.5f);
  for (int k = 0; k < 3; ++k) reference.rgb[k] = -1.0f, estimate.rgb[k] = 9.0f;  // pixel 0 masked, and wrong
  EXPECT_NEAR(scoreImage(estimate, reference, "r").psnr, 120.0, 1e-9);
  const ViewError e = errorAgainstPhoto({estimate, Image(2, 1)}, reference);
  EXPECT_EQ(e.samples, 3u);
  EXPECT_EQ(e.errorMean, 0.0);
  EXPECT_EQ(e.error.rgb[0], 0.0f);
  EXPECT_DOUBLE_EQ(e.referenceMean, 0.5);
  std::fill(reference.rgb.begin(), reference.rgb.end(), -1.0f);
  EXPECT_THROW(scoreImage(estimate, reference, "all masked"), Error);
}
