// The scale estimator of lights seen only saturated (product/clipped_light_scale.h) run on a
// prepared capture at its ground truth, apart from the fit's state: every texel at its true albedo
// (objects' uncovered texels at their covered texels' mean), every object's true roughness and
// specular (or the fit's init, 0.5 / 0.5), the true emission with every light divided by DIVIDE.
// A scale of DIVIDE for each light is exact; what it gives instead is the estimator's own error on
// this capture. Prints, per seed, the fit's line, each light's scale and error and each object's
// own most uniform scale.
// Usage: scale_at_truth WORK TRUTH_SCENE.json [DIVIDE=1.5] [RESOLUTION=512] [SEEDS=2]
//                       [MATERIALS=truth|init] [CHOICE=1] [SHOWN=1]
// (CHOICE, SHOWN: clipped_scale_material_choice, clipped_scale_shown_radiance.)
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "core/error.h"
#include "product/evaluate.h"
#include "product/light_decisions.h"

namespace {

using namespace relume;

// The truth's albedo in the work's atlas at `res`, uncovered valid texels at their object's mean.
Texture truthAlbedo(const Workspace& w, const TexelSpace& space, const SceneDescription& truth) {
  const int res = space.resolution;
  const Image covered = truthAlbedoInAtlas(w.mesh, truth, res);
  const int objects = w.mesh.objectCount;
  std::vector<Eigen::Array4d> mean(objects, Eigen::Array4d::Zero());
  for (size_t t = 0; t < space.map.texelCount(); ++t)
    if (space.map.covered(t)) {
      const Color c = covered.at(static_cast<int>(t % res), static_cast<int>(t / res));
      mean[space.objectOf(t, w.mesh)] += Eigen::Array4d(c[0], c[1], c[2], 1.0);
    }
  Texture albedo(res, res, Color::Constant(0.5f));
  for (size_t t = 0; t < space.map.texelCount(); ++t) {
    if (!space.map.valid(t)) continue;
    const Eigen::Array4d& m = mean[space.objectOf(t, w.mesh)];
    const Color c = space.map.covered(t) ? covered.at(static_cast<int>(t % res), static_cast<int>(t / res))
                    : m[3] > 0           ? Color((m.head<3>() / m[3]).cast<float>())
                                         : Color::Constant(0.5f);
    for (int k = 0; k < 3; ++k) albedo.rgb[3 * t + k] = c[k];
  }
  return albedo;
}

int run(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: scale_at_truth WORK TRUTH_SCENE.json [DIVIDE=1.5] [RESOLUTION=512] [SEEDS=2] "
                 "[MATERIALS=truth|init] [CHOICE=1] [SHOWN=1]\n");
    return 2;
  }
  const double divide = argc > 3 ? std::atof(argv[3]) : 1.5;
  const int res = argc > 4 ? std::atoi(argv[4]) : 512;
  const int seeds = argc > 5 ? std::atoi(argv[5]) : 2;
  const bool trueMaterials = argc <= 6 || std::strcmp(argv[6], "init") != 0;
  FitConfig config;
  config.clippedScaleMaterialChoice = argc <= 7 || std::atoi(argv[7]) != 0;
  config.clippedScaleShownRadiance = argc <= 8 || std::atoi(argv[8]) != 0;
  if (!(divide > 0) || res < 16 || seeds < 1) fail("scale_at_truth: DIVIDE > 0, RESOLUTION >= 16, SEEDS >= 1");

  const Workspace w(argv[1]);
  const SceneDescription truth = loadSceneFile(argv[2]);
  const int objects = w.mesh.objectCount;
  if (truth.appearance.objectCount() != objects)
    fail("{}: {} objects, the work folder {}", argv[2], truth.appearance.objectCount(), objects);
  const TexelSpace space(w, res);

  Appearance a(objects);
  for (const auto& [id, name] : w.names)
    if (id >= 0 && id < objects) a.names[id] = name;
  std::fill(a.albedoFromTexture.begin(), a.albedoFromTexture.end(), 1);
  a.albedo = truthAlbedo(w, space, truth);
  std::vector<uint8_t> emitter(objects, 0), outOfModel(objects, 0);
  for (int o = 0; o < objects; ++o) {
    a.roughness[o] = trueMaterials ? truth.appearance.roughness[o] : 0.5f;
    a.specular[o] = trueMaterials ? truth.appearance.specular[o] : 0.5f;
    emitter[o] = truth.appearance.isEmissive(o);
    a.emission[o] = truth.appearance.emission[o] / static_cast<float>(divide);
  }

  FrameGains gains(resolveFrameGains(config.frameGains, w.frames, *w.store, w.kept), w.frames.size(), w.kept,
                   config.gainReferenceFrame, config.gainMemory);
  if (gains.estimated()) gains.start(w.consistencyGains());
  PathSettings path;
  path.maxDepth = config.maxDepth;
  path.russianRoulette = config.russianRoulette;
  path.rouletteDepth = config.rouletteDepth;

  std::printf("divide %.4g, %d^2, materials %s, choice %d, shown radiance %d\n", divide, res,
              trueMaterials ? "truth" : "init", config.clippedScaleMaterialChoice, config.clippedScaleShownRadiance);
  for (int seed = 1; seed <= seeds; ++seed) {
    Appearance scaled = a;
    const ClippedLightScale s = scaleClippedLights(w, space, scaled, emitter, outOfModel, gains, path,
                                                   clippedLightSettings(config), static_cast<uint64_t>(seed));
    std::printf("seed %d: %s\n", seed, s.why.c_str());
    for (size_t k = 0; k < s.lights.size(); ++k) {
      const int o = s.lights[k];
      std::printf("  %s: scale %.4f (log error %.3f), truth / emission after %.4f\n", a.names[o].c_str(),
                  s.fit.scale[k], s.fit.logError[k],
                  luminance(truth.appearance.emission[o]) / luminance(scaled.emission[o]));
    }
    std::printf("  objects' own scales:");
    for (const auto& [o, own] : s.fit.perObject) std::printf(" %s %.3g;", a.names[o].c_str(), own);
    std::printf("\n");
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::warn);
  try {
    return run(argc, argv);
  } catch (const relume::Error& e) {
    std::fprintf(stderr, "scale_at_truth: %s\n", e.what());
    return 1;
  }
}
