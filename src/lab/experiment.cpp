#include "lab/experiment.h"

#include <tbb/parallel_for.h>

#include "sampling/samplers.h"
#include "core/random_streams.h"

namespace relume {

std::vector<BatchRay> raysFromCameras(const Scene& scene, const Appearance& truth, const std::vector<Camera>& cameras,
                                      const ExperimentOptions& o) {
  const LightSampler lights(scene, truth);
  const AppearanceScope scope = AppearanceScope::uniform(truth);
  PathSettings path;
  path.maxDepth = o.maxDepth;
  std::vector<BatchRay> rays(o.rays);
  tbb::parallel_for(0, o.rays, [&](int j) {
    Pcg32 rng(hashTuple({o.seed, static_cast<uint64_t>(j), streamTag(RandomStream::ExperimentRays)}));
    const Camera& cam = cameras[rng.nextU32() % cameras.size()];
    BatchRay& r = rays[j];
    r.origin = cam.position;
    r.dir = randomPixelRay(cam, rng).value_or(std::pair{Vec2::Zero().eval(), Vec3(cam.rotation.col(2))}).second;
    Color sum = Color::Zero();
    for (int s = 0; s < o.referenceSpp; ++s) {
      Pcg32 pr(hashTuple({o.seed, static_cast<uint64_t>(j), static_cast<uint64_t>(s),
                          streamTag(RandomStream::ExperimentPerturbation)}));
      sum += tracePath(scene, lights, scope, path, r.origin, r.dir, pr);
    }
    r.reference = sum / static_cast<float>(o.referenceSpp);
    r.clip.high = o.clipHigh;
  });
  return rays;
}

Appearance perturbAppearance(const Appearance& a, uint64_t seed) {
  Appearance p = a;
  Pcg32 rng(seed);
  for (ParamGroup& g : paramGroups(p)) {
    if (g.kind == ParamKind::Emission || g.kind == ParamKind::EmissionTexture) {  // radiance: a relative change
      for (float& v : g.values) v *= 0.8f;
    } else if (g.textured()) {  // towards the middle of the domain, keeping the texture's pattern
      for (float& v : g.values) v = g.lo + 0.7f * (v - g.lo) + 0.1f * (g.hi - g.lo);
    } else {  // per-object scalars: a random move, kept off the domain's edges
      const float w = g.hi - g.lo;
      for (float& v : g.values)
        v = std::clamp(v + 0.35f * w * (rng.next1D() - 0.5f), g.lo + 0.1f * w, g.hi - 0.05f * w);
    }
  }
  return p;
}

GradientExperiment makeGradientExperiment(SceneDescription truth, const std::vector<Camera>& cameras,
                                          const ExperimentOptions& o) {
  GradientExperiment e{std::move(truth), Appearance(), {}};
  Appearance& a = e.truth.appearance;
  for (Color& c : a.emission) c *= o.emissionScale;
  requireEmissionBound(a, fmt::format("emission scale {:g}", o.emissionScale));
  if (o.emissionTextures && a.emissionTextures.empty())
    allocateEmissionTextures(a, e.truth.mesh, o.atlasResolution, [](float u, float v) { return 0.6f + 0.8f * u * v; });
  const Scene scene(e.truth.mesh);
  e.rays = raysFromCameras(scene, a, cameras, o);
  e.current = perturbAppearance(a, o.seed);
  return e;
}

GradientExperiment makeGradientExperiment(SynthSceneKind kind, const ExperimentOptions& o) {
  return makeGradientExperiment(makeSynthScene(kind, o.atlasResolution).scene, synthCameraPath(kind, 8, 160, 120, 0.25),
                                o);
}

}  // namespace relume
