// Unidirectional path tracer with next-event estimation and MIS (power heuristic).
// One kernel serves rendering and the adjoint solver: it reports each term of the estimate to an
// Observer (a no-op for rendering), and evaluates each term with the Appearance its
// AppearanceScope names, while every sampling decision (lobe choice, directions, pdfs, MIS
// weights, light choice, Russian roulette) uses `scope.sampling` only: sampling is detached.
#pragma once
#include <array>
#include <type_traits>

#include "core/rng.h"
#include "core/warp.h"
#include "render/bsdf.h"
#include "render/lights.h"

namespace relume {

// Path length: the number of scattering vertices, each with next-event estimation (0 = emission
// seen directly only, 1 = direct lighting, N = N - 1 indirect bounces). Cycles' "max bounces" B
// counts indirect bounces, so it equals depth B + 1; the default 9 is Cycles' default 8 (measured
// against Cycles 3.4: README "Agreement with Blender Cycles").
inline constexpr int kDefaultMaxDepth = 9;

struct PathSettings {
  int maxDepth = kDefaultMaxDepth;
  bool russianRoulette = false;
  int rouletteDepth = 3;  // vertices always reached; roulette decides each bounce after them
};

// Which appearance each term is evaluated with. Rendering uses one appearance everywhere; gradient
// checks perturb the terms a gradient mode differentiates (e.g. only the first vertex).
struct AppearanceScope {
  const Appearance* sampling;
  const Appearance* bsdfFirst;      // BSDF at the first vertex x0
  const Appearance* bsdfDeep;       // BSDF at x1, x2, ...
  const Appearance* emissionFirst;  // emission seen directly, or reached from x0 (NEE or BSDF)
  const Appearance* emissionDeep;   // emission reached from x1, x2, ...
  static AppearanceScope uniform(const Appearance& a) { return {&a, &a, &a, &a, &a}; }
  const Appearance& bsdf(int depth) const { return depth == 0 ? *bsdfFirst : *bsdfDeep; }
  const Appearance& emission(int fromVertex) const { return fromVertex <= 0 ? *emissionFirst : *emissionDeep; }
};

inline BsdfParams bsdfParamsAt(const Appearance& a, const SurfaceHit& hit) {
  return {a.albedoAt(hit.object, hit.uv), a.roughness[hit.object], a.specular[hit.object], a.model};
}

// Front-facing Lambertian emission of `hit` seen along -dir.
inline Color emittedRadiance(const Appearance& a, const SurfaceHit& hit, const Vec3& dir) {
  if (hit.ng.dot(dir) >= 0.0f) return Color::Zero();
  return a.emissionAt(hit.object, hit.uv);
}

// Observer interface (all no-ops here). depth = index of the vertex the event happens at.
struct NullPathObserver {
  // A differentiating observer needs events for terms whose value is 0 but whose derivative is
  // not (a surface with zero emission, a zero BSDF, a path whose throughput became 0).
  static constexpr bool kDifferentiating = false;
  // A ray was traced (statistics; the profiler replays them through Embree alone).
  void traced(const Vec3& origin, const Vec3& dir, float tmax, bool shadow) {}
  // A scattering or terminal vertex was reached with throughput beta (before its own terms).
  void vertex(int depth, const SurfaceHit& hit, const ShadingFrame& frame, const Vec3& woLocal, const Color& beta) {}
  // Emission at vertex `depth`, MIS-weighted, not yet multiplied by beta.
  void emission(int depth, const SurfaceHit& hit, float mis, const Color& le) {}
  // NEE at vertex `depth`: contribution = beta * f * cosI * scale * le with scale = mis / pdf.
  void nee(int depth, const Vec3& wiLocal, const Color& f, float cosI, float scale, const Color& le,
           const SurfaceHit& light) {}
  // BSDF sample at vertex `depth`: next beta = beta * f * cosI / (pdf * survival).
  void scatter(int depth, const Vec3& wiLocal, const Color& f, float cosI, float pdf, float survival) {}
};

// Everything a path carries from one vertex to the next.
struct PathState {
  Vec3 origin = Vec3::Zero(), dir = Vec3::UnitZ();  // the ray to the next vertex
  Color L = Color::Zero(), beta = Color::Constant(1.0f), betaSampling = Color::Constant(1.0f);
  float prevPdf = 0.0f;
  int depth = 0;  // index of the next vertex
};

// Vertex s.depth of a path, at `hit`: the emission reached there, next-event estimation, and the
// BSDF sample that sets the path's next ray. False: the path ends here.
template <class Observer>
bool shadeVertex(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                 const PathSettings& settings, PathState& s, const SurfaceHit& hit, Pcg32& rng, Observer& obs) {
  const bool frontFacing = hit.ng.dot(s.dir) < 0.0f;
  ShadingFrame frame(frontFacing ? hit.ns : Vec3(-hit.ns));  // two-sided BSDF: frame on the viewer's side
  const Vec3 wo = frame.toLocal(-s.dir);
  obs.vertex(s.depth, hit, frame, wo, s.beta);

  // Emission reached by the camera ray or by BSDF sampling from the previous vertex.
  const Color le = emittedRadiance(scope.emission(s.depth - 1), hit, s.dir);
  if ((le != 0.0f).any() || (std::decay_t<Observer>::kDifferentiating && frontFacing)) {
    float mis = 1.0f;
    if (s.depth > 0) {
      const float pdfLight = lights.pdfArea(hit.object) * hit.t * hit.t / std::abs(hit.ng.dot(s.dir));
      mis = powerHeuristic(s.prevPdf, pdfLight);
    }
    obs.emission(s.depth, hit, mis, le);
    s.L += s.beta * mis * le;
  }
  if (s.depth >= settings.maxDepth) return false;

  const bool frozen = &scope.bsdf(s.depth) != scope.sampling;  // evaluate with other parameters
  const BsdfParams sampleParams = bsdfParamsAt(*scope.sampling, hit);
  const BsdfParams evalParams = frozen ? bsdfParamsAt(scope.bsdf(s.depth), hit) : sampleParams;
  const VertexBsdf bsdf(sampleParams, wo);
  // Next-event estimation.
  const float uObject = rng.next1D(), uTri = rng.next1D();
  const Vec2 uPoint(rng.next1D(), rng.next1D());
  if (const auto ls = lights.sample(uObject, uTri, uPoint)) {
    Vec3 toLight = ls->hit.p - hit.p;
    const float dist2 = toLight.squaredNorm();
    const float dist = std::sqrt(dist2);
    toLight /= dist;
    const float cosLight = -ls->hit.ng.dot(toLight);
    const Vec3 wi = frame.toLocal(toLight);
    if (cosLight > 0.0f && wi.z() > 0.0f && dist > 0.0f) {
      const Color leLight = scope.emission(s.depth).emissionAt(ls->hit.object, ls->hit.uv);
      const BsdfEval sampled = bsdf.eval(wi, kBsdfValue | kBsdfPdf);
      const Color f = frozen ? evalBsdf(evalParams, wo, wi).f : sampled.f;
      if ((leLight != 0.0f).any() && (f.maxCoeff() > 0.0f || std::decay_t<Observer>::kDifferentiating)) {
        // Both ends are offset off their surfaces and the shadow ray joins them: a ray from the
        // offset origin along toLight would cross the light's own plane before a shortened tmax
        // wherever the light is seen at a slant, and count the light as its own occluder.
        const Vec3 o = Scene::offsetOrigin(hit, toLight);
        Vec3 shadowDir = Scene::offsetOrigin(ls->hit, -toLight) - o;
        const float tmax = shadowDir.norm();
        bool visible = true;  // ends within an epsilon of each other: nothing between, no ray to trace
        if (tmax > 0.0f) {
          shadowDir /= tmax;
          obs.traced(o, shadowDir, tmax, true);
          visible = !scene.occluded(o, shadowDir, tmax);
        }
        if (visible) {
          const float pdfLight = ls->pdfArea * dist2 / cosLight;
          const float mis = powerHeuristic(pdfLight, sampled.pdf);
          const float scale = mis / pdfLight;
          obs.nee(s.depth, wi, f, wi.z(), scale, leLight, ls->hit);
          s.L += s.beta * f * (wi.z() * scale) * leLight;
        }
      }
    }
  }

  // BSDF sampling.
  const float uLobe = rng.next1D();
  const Vec2 uDir(rng.next1D(), rng.next1D());
  const auto bs = bsdf.sample(uLobe, uDir);
  if (!bs) return false;
  const Color f = frozen ? evalBsdf(evalParams, wo, bs->wi).f : bs->f;
  float survival = 1.0f;
  s.betaSampling *= bs->weight;
  if (settings.russianRoulette && s.depth + 1 >= settings.rouletteDepth) {
    survival = std::clamp(s.betaSampling.maxCoeff(), 0.05f, 0.95f);
    if (rng.next1D() >= survival) return false;
    s.betaSampling /= survival;
  }
  obs.scatter(s.depth, bs->wi, f, bs->wi.z(), bs->pdf, survival);
  s.beta *= f * (bs->wi.z() / (bs->pdf * survival));
  if (s.beta.maxCoeff() <= 0.0f && !std::decay_t<Observer>::kDifferentiating) return false;
  s.dir = frame.toWorld(bs->wi);
  s.origin = Scene::offsetOrigin(hit, s.dir);
  s.prevPdf = bs->pdf;
  ++s.depth;
  return true;
}

// Paths traced in lockstep, one vertex of each in turn (path i gives exactly what tracePath gives
// for its ray, seed and observer): a path's face record and albedo texels are fetched while the
// group's other rays are traversed, so the cache misses that dominate shading overlap.
inline constexpr int kPathGroup = 8;

template <class Observer>
void tracePathGroup(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                    const PathSettings& settings, int count, PathState* paths, Pcg32* rngs, Observer* obs) {
  std::array<int, kPathGroup> live;
  std::array<Scene::PendingHit, kPathGroup> pending;
  std::array<std::optional<SurfaceHit>, kPathGroup> hits;
  int n = 0;
  for (int i = 0; i < count; ++i) live[n++] = i;
  while (n > 0) {
    for (int k = 0; k < n; ++k) pending[k] = scene.beginIntersect(paths[live[k]].origin, paths[live[k]].dir);
    for (int k = 0; k < n; ++k) {
      const PathState& s = paths[live[k]];
      hits[k] = scene.endIntersect(pending[k], s.origin, s.dir);
      obs[live[k]].traced(s.origin, s.dir, INFINITY, false);
      if (hits[k]) scope.sampling->prefetchAlbedo(hits[k]->object, hits[k]->uv);
    }
    int next = 0;
    for (int k = 0; k < n; ++k)
      if (hits[k] && shadeVertex(scene, lights, scope, settings, paths[live[k]], *hits[k], rngs[live[k]], obs[live[k]]))
        live[next++] = live[k];
    n = next;
  }
}

template <class Observer = NullPathObserver>
Color tracePath(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                const PathSettings& settings, Vec3 origin, Vec3 dir, Pcg32& rng, Observer&& obs = Observer{}) {
  PathState s{origin, dir};
  tracePathGroup(scene, lights, scope, settings, 1, &s, &rng, &obs);
  return s.L;
}

// Rays [begin, end) through tracePathGroup: start(j, path, rng, observer) sets up ray j's path
// (false: skip the ray), done(j, L, observer) takes its radiance.
template <class Observer, class Start, class Done>
void tracePathsGrouped(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                       const PathSettings& settings, size_t begin, size_t end, std::array<Observer, kPathGroup>& obs,
                       Start&& start, Done&& done) {
  std::array<PathState, kPathGroup> paths;
  std::array<Pcg32, kPathGroup> rngs;
  std::array<size_t, kPathGroup> ray;
  for (size_t j = begin; j < end;) {
    int count = 0;
    for (; j < end && count < kPathGroup; ++j) {
      paths[count] = PathState{};
      if (start(j, paths[count], rngs[count], obs[count])) ray[count++] = j;
    }
    tracePathGroup(scene, lights, scope, settings, count, paths.data(), rngs.data(), obs.data());
    for (int i = 0; i < count; ++i) done(ray[i], paths[i].L, obs[i]);
  }
}

}  // namespace relume
