// The scale estimator of lights seen only saturated (product/clipped_light_scale.h) run on a
// prepared capture at its ground truth, apart from the fit's state: every texel at its true albedo
// (objects' uncovered texels at their covered texels' mean), every object's true roughness and
// specular (or the fit's init, 0.5 / 0.5), the true emission with every light divided by `divide`.
// A scale of `divide` for each light is exact; what it gives instead is the estimator's own error
// on this capture. With albedo=absorbed each albedo is the truth's times `divide`, at most 1: what
// a fit holds while its lights are that much too dark (its albedo takes up the missing light up to
// its ceiling). Prints, per seed, the fit's line, each light's scale and error, each object's
// own most uniform scale and the objects whose albedo ceiling bounds the lights the most.
// Usage: scale_at_truth WORK TRUTH_SCENE.json [KEY=VALUE...] with keys (defaults)
//   divide (1.5), resolution (512), seeds (2), materials (truth | init), albedo (truth | absorbed),
//   choice (1: clipped_scale_material_choice), shown (1: clipped_scale_shown_radiance),
//   paths (8: the paths traced per ray for each term), texels (0: the fit's texels drawn per object),
//   ceiling (1: clipped_scale_albedo_ceiling), diagnose (0; 1: also the model's error per object,
//   below)
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "core/check.h"
#include "core/error.h"
#include "core/math.h"
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

// Where the estimator's model misses, seen at the true scale: each texel's albedo from its terms at
// every light's true scale s (`scale`; the texels of the first fit, under the fit's materials),
// (I - s.G - G_R) / (s.D + R), over the truth's, in red, green and blue. Per object the median of
// that ratio and the slope of its log against the share of the texel's light that comes straight
// from the clipped lights, s.D / (s.D + R): a scale that makes the albedo uniform moves by about
// that slope in log (a negative slope pulls it down), so an object with a slope beyond its noise
// pulls the pooled scale by its model's error, not by its light.
void printModelError(const ClippedLightScale& s, const Texture& truth, double scale, const Appearance& a) {
  struct Sums {
    std::vector<double> logRatio;
    double f = 0, ff = 0, y = 0, fy = 0;
  };
  std::map<int, Sums> perObject;
  Sums all;
  for (int band = 0; band < 3; ++band)
    for (const ScaleTexel& t : s.texels[band]) {
      const size_t K = t.mean.size() - 1;
      double direct = 0, specular = 0;
      for (size_t c = 0; c < K; ++c) direct += scale * t.mean[c];
      if (!t.specular.empty()) {
        for (size_t c = 0; c < K; ++c) specular += scale * t.specular[c];
        specular += t.specular[K];
      }
      CHECK(3 * size_t{t.texel} + 2 < truth.rgb.size());
      const double received = direct + t.mean[K], shown = t.shown - specular, albedo = truth.rgb[3 * t.texel + band];
      if (!(received > 0 && shown > 0 && albedo > 0.02)) continue;
      const double y = std::log(shown / received / albedo), f = direct / received;
      for (Sums* x : {&perObject[t.object], &all}) {
        x->logRatio.push_back(y);
        x->f += f, x->ff += f * f, x->y += y, x->fy += f * y;
      }
    }
  auto slope = [](const Sums& x) {
    const double n = static_cast<double>(x.logRatio.size());
    return (n * x.fy - x.f * x.y) / (n * x.ff - x.f * x.f);
  };
  std::printf("  at the true scale, albedo over the truth's (median; slope of its log in the direct share):");
  auto print = [&](const std::string& name, const Sums& x) {
    std::printf(" %s %.3f", name.c_str(), std::exp(medianOf(x.logRatio)));
    if (const double b = slope(x); std::isfinite(b)) std::printf(" (%+.3f)", b);  // none without direct light
    std::printf(";");
  };
  for (const auto& [o, x] : perObject) print(a.names[o], x);
  print("all", all);
  std::printf("\n");
}

int run(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: scale_at_truth WORK TRUTH_SCENE.json [divide=1.5] [resolution=512] [seeds=2] "
                         "[materials=truth|init] [albedo=truth|absorbed] [choice=1] [shown=1] [ceiling=1] "
                         "[diagnose=0]\n");
    return 2;
  }
  std::map<std::string, std::string> keys = {{"divide", "1.5"},    {"resolution", "512"}, {"seeds", "2"},
                                             {"materials", "truth"}, {"albedo", "truth"},  {"choice", "1"},
                                             {"shown", "1"},         {"paths", "8"},        {"texels", "0"},
                                             {"ceiling", "1"},       {"diagnose", "0"}};
  for (int i = 3; i < argc; ++i) {
    const std::string arg = argv[i];
    const size_t eq = arg.find('=');
    if (eq == std::string::npos || !keys.count(arg.substr(0, eq))) fail("scale_at_truth: unknown argument '{}'", arg);
    keys[arg.substr(0, eq)] = arg.substr(eq + 1);
  }
  const double divide = std::atof(keys["divide"].c_str());
  const int res = std::atoi(keys["resolution"].c_str()), seeds = std::atoi(keys["seeds"].c_str());
  const bool trueMaterials = keys["materials"] == "truth", absorbed = keys["albedo"] == "absorbed";
  FitConfig config;
  config.clippedScaleMaterialChoice = keys["choice"] != "0";
  config.clippedScaleShownRadiance = keys["shown"] != "0";
  config.clippedScaleAlbedoCeiling = keys["ceiling"] != "0";
  if (!(divide > 0) || res < 16 || seeds < 1 || (!trueMaterials && keys["materials"] != "init") ||
      (!absorbed && keys["albedo"] != "truth"))
    fail("scale_at_truth: divide > 0, resolution >= 16, seeds >= 1, materials truth or init, albedo truth or absorbed");

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
  const Texture trueAlbedo = truthAlbedo(w, space, truth);
  a.albedo = trueAlbedo;
  if (absorbed)
    for (float& x : a.albedo.rgb) x = std::min(1.0f, x * static_cast<float>(divide));
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

  std::printf("divide %.4g, %d^2, materials %s, albedo %s, choice %d, shown radiance %d, paths %s, texels %s\n",
              divide, res, keys["materials"].c_str(), keys["albedo"].c_str(), config.clippedScaleMaterialChoice,
              config.clippedScaleShownRadiance, keys["paths"].c_str(), keys["texels"].c_str());
  for (int seed = 1; seed <= seeds; ++seed) {
    Appearance scaled = a;
    ClippedLightSettings settings = clippedLightSettings(config);
    settings.pathsPerRay = std::atoi(keys["paths"].c_str());
    settings.keepTexels = keys["diagnose"] == "1";
    if (const int texels = std::atoi(keys["texels"].c_str()); texels > 0) settings.texelsPerObject = texels;
    const ClippedLightScale s = scaleClippedLights(w, space, scaled, emitter, outOfModel, gains, path, settings,
                                                   static_cast<uint64_t>(seed));
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
    // The objects whose albedo bounds the lights from below the most (at the scales the uniformity gave).
    std::vector<CeilingBound> bounds = s.ceiling.perObject;
    const auto below = [&](const CeilingBound& b) { return b.factor - settings.ceilingSigmas * b.error; };
    std::sort(bounds.begin(), bounds.end(), [&](const auto& x, const auto& y) { return below(x) > below(y); });
    std::printf("  albedo ceiling x %.4f; objects' bounds:", s.ceiling.factor);
    for (size_t i = 0; i < std::min<size_t>(bounds.size(), 10); ++i)
      std::printf(" %s %.3g+-%.2g;", a.names[bounds[i].object].c_str(), bounds[i].factor, bounds[i].error);
    std::printf("\n");
    if (settings.keepTexels) printModelError(s, trueAlbedo, divide, a);
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
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
