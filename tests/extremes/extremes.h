// Shared pieces of the numerical-extremes suite (issue 12): finiteness checks over everything the
// solver and the fit produce, small gradient experiments, a gradient check that is right, not
// only finite, and a tiny prepared capture with a hook to damage it before `prepare` runs.
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <span>
#include <string>

#include "adjoint/gradcheck.h"
#include "io/json.h"
#include "lab/experiment.h"
#include "product/fit.h"
#include "product/prepare.h"

namespace relume::extremes {

inline bool allFinite(std::span<const float> v) {
  return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
}
inline bool allFinite(const std::vector<Color>& v) {
  return std::all_of(v.begin(), v.end(), [](const Color& c) { return c.allFinite(); });
}
inline bool allFinite(const Gradients& g) {
  bool ok = allFinite(g.albedo) && allFinite(g.albedoCurvature) && allFinite(g.objects);
  for (const std::vector<float>& t : g.emissionTexture) ok = ok && allFinite(t);
  return ok;
}
inline bool allFinite(Appearance& a) {
  for (const ParamGroup& g : paramGroups(a))
    if (!allFinite(g.values)) return false;
  return true;
}

// Cornell box (textured albedo, glossy boxes, one ceiling light), 96 rays, depth 4: every
// parameter kind is reached and a gradient check takes well under a second.
inline GradientExperiment cornell(float emissionScale = 1.0f) {
  ExperimentOptions o;
  o.rays = 96;
  o.atlasResolution = 32;
  o.referenceSpp = 2;
  o.maxDepth = 4;
  o.emissionScale = emissionScale;
  return makeGradientExperiment(SynthSceneKind::Cornell, o);
}

// Radiance estimates of the batch under `a` (the primal pass's seeds).
inline std::vector<Color> estimates(const Scene& scene, const Appearance& a, const std::vector<BatchRay>& rays,
                                    int maxDepth, uint64_t seed = 0) {
  const LightSampler lights(scene, a);
  AdjointSettings s;
  s.seed = seed;
  s.path.maxDepth = maxDepth;
  return traceRays(scene, lights, AppearanceScope::uniform(a), rays, s.path,
                   [&](size_t j) { return primalSeed(s, 0, j); });
}

// The claim "finite and right": the estimates and every gradient buffer (Gauss-Newton curvature
// included) are finite, and each gradient of `kinds` matches the central finite difference of
// its own estimator with sampling frozen at the unperturbed parameters (common random numbers:
// gradcheck level 1, 2e-3 relative plus the float-rounding floor), in `full` mode so that every
// vertex's parameters are differentiated. Returns the check's rows (which parameters it reached).
inline GradcheckReport expectFiniteAndRight(const TriangleMesh& mesh, const Appearance& current,
                                            const std::vector<BatchRay>& rays, const std::vector<ParamKind>& kinds,
                                            int maxDepth, const std::string& what) {
  const Scene scene(mesh);
  EXPECT_TRUE(allFinite(estimates(scene, current, rays, maxDepth))) << what;
  GradcheckOptions o;
  o.kinds = kinds;
  o.settings.mode = GradientMode::Full;
  o.settings.path.maxDepth = maxDepth;
  o.paramsPerKind = 2;
  o.level2 = false;
  const LightSampler lights(scene, current);
  Gradients g(current, true);
  const GradientResult r = computeGradients(scene, current, lights, rays, o.settings, 0, g);
  EXPECT_TRUE(std::isfinite(r.loss)) << what;
  EXPECT_TRUE(allFinite(g)) << what;
  const GradcheckReport report = runGradcheck(scene, current, rays, o);
  EXPECT_FALSE(report.rows.empty()) << what;
  EXPECT_TRUE(report.pass()) << what << "\n" << report.table();
  return report;
}
inline GradcheckReport expectFiniteAndRight(const GradientExperiment& e, const std::vector<ParamKind>& kinds,
                                            const std::string& what) {
  return expectFiniteAndRight(e.truth.mesh, e.current, e.rays, kinds, 4, what);
}

// A tiny Cornell capture (32x24 frames, 4 spp) in a fresh folder DIR/capture, `edit`ed, then
// prepared at `resolutions` (charts padded for the first) into DIR/work. Each test names its own
// folder (CTest runs them in parallel).
inline std::filesystem::path tinyCapture(const std::string& name, int frames,
                                         const std::function<void(const std::filesystem::path&)>& edit = {},
                                         const std::vector<int>& resolutions = {64}) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("relume_extremes_" + name);
  std::filesystem::remove_all(dir);
  SynthCaptureOptions c;
  c.kind = SynthSceneKind::Cornell;
  c.out = dir / "capture";
  c.frames = frames, c.testFrames = 1, c.width = 32, c.height = 24, c.spp = 4, c.testSpp = 4, c.atlasResolution = 64;
  writeSynthCapture(c);
  if (edit) edit(c.out);
  PrepareOptions po;
  po.resolutions = resolutions;
  po.atlas.gutterResolution = resolutions.front();
  prepareCapture(c.out, dir / "work", po);
  return dir;
}

// A whole fit schedule (emission, albedo, materials, emission textures) in a few dozen small
// iterations.
inline FitConfig tinyFit() {
  FitConfig c;
  c.batchTexels = 256;
  c.framesPerTexel = 2;
  c.maxDepth = 3;
  c.emissionIterations = 60;
  c.materialIterations = 10;
  c.albedoPasses = 4;
  c.emissionTextureIterations = 10;
  c.highlightMinPairs = 1, c.highlightMinContrast = -1e9f;  // fit every object seen with a light reflected
  return c;
}

// The fit in DIR/work ended with a bounded result: every parameter finite and inside its domain
// (the optimisers project after each step), and every loss it logged finite.
inline void expectBoundedFit(const std::filesystem::path& dir) {
  SceneDescription fit = loadSceneFile(dir / "work" / "result" / "scene.json");
  EXPECT_TRUE(allFinite(fit.appearance));
  for (const ParamGroup& g : paramGroups(fit.appearance))
    for (float v : g.values) EXPECT_TRUE(v >= g.lo && v <= g.hi) << g.name() << " " << v;
  EXPECT_TRUE(std::isfinite(readJson(dir / "work" / "result" / "materials.json").at("final_loss").get<double>()));
  std::ifstream metrics(dir / "work" / "metrics.jsonl");
  int lines = 0;
  for (std::string line; std::getline(metrics, line); ++lines)
    EXPECT_TRUE(std::isfinite(Json::parse(line).at("loss").get<double>())) << line;
  EXPECT_GT(lines, 0);
}

}  // namespace relume::extremes
