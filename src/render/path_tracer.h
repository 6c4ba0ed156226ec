// Unidirectional path tracer with next-event estimation and MIS (power heuristic).
// One kernel serves rendering and the adjoint solver: it reports each term of the estimate to an
// Observer (a no-op for rendering), and evaluates each term with the Appearance its
// AppearanceScope names, while every sampling decision (lobe choice, directions, pdfs, MIS
// weights, light choice, Russian roulette) uses `scope.sampling` only: sampling is detached.
#pragma once
#include <span>
#include <type_traits>

#include "core/rng.h"
#include "core/warp.h"
#include "render/bsdf.h"
#include "render/lights.h"

namespace relume {

// Path length: the number of scattering vertices, each with next-event estimation (0 = emission
// seen directly only, 1 = direct lighting, N = N - 1 indirect bounces). Cycles' "max bounces" B
// counts indirect bounces, so it equals depth B + 1; the default 9 is Cycles' default 8 (measured
// against Cycles 3.4: docs/notes/2026-11-22-cycles-agreement.md).
inline constexpr int kDefaultMaxDepth = 9;

// Paths a thread traces together (tracePaths below): wide enough that a whole bounce's other paths
// lie between a prefetch and its use, narrow enough that their state stays in the L2 cache.
inline constexpr size_t kWavefrontWidth = 256;

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
  const Appearance* bsdfDeep;       // BSDF at x1 (unless bsdfSecond is set), x2, ...
  const Appearance* emissionFirst;  // emission seen directly, or reached from x0 (NEE or BSDF)
  const Appearance* emissionDeep;   // emission reached from x1, x2, ...
  const Appearance* bsdfSecond = nullptr;  // BSDF at x1 when set (else bsdfDeep's)
  static AppearanceScope uniform(const Appearance& a) { return {&a, &a, &a, &a, &a}; }
  const Appearance& bsdf(int depth) const {
    return depth == 0 ? *bsdfFirst : depth == 1 && bsdfSecond ? *bsdfSecond : *bsdfDeep;
  }
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

// One path of a wavefront: the caller sets its ray and generator (and, optionally, where to keep
// its first vertex) and reads its estimate L; the rest carries the path from one bounce to the next.
struct PathSlot {
  Vec3 origin, dir;
  Pcg32 rng;
  SurfaceHit* firstHit = nullptr;
  Color L = Color::Zero();
  Color beta = Color::Constant(1.0f), betaSampling = Color::Constant(1.0f);
  float prevPdf = 0.0f;
  bool alive = true;
  RayHit next;     // the closest hit of the current ray, before its attributes are read
  SurfaceHit hit;  // ... and after
  // Next-event estimation's random numbers (triangle, point), its pick (the emitter, then the
  // triangle) and its light point, drawn and fetched in earlier phases of the bounce (tracePaths);
  // no light point when the scene has no emitter.
  float uLightTriangle = 0;
  Vec2 uLightPoint = Vec2::Zero();
  LightPick lightPick;
  std::optional<LightSample> light;

  PathSlot() = default;
  PathSlot(const Vec3& o, const Vec3& d, const Pcg32& r, SurfaceHit* first = nullptr)
      : origin(o), dir(d), rng(r), firstHit(first) {}
};

// Everything a path does at vertex `depth` once its hit and its light point (tracePaths) are
// known: emission, next-event estimation and the BSDF sample that sets its next ray (or ends it).
template <class Observer>
void shadeVertex(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                 const PathSettings& settings, int depth, PathSlot& path, Observer& obs) {
  constexpr bool kDifferentiating = std::decay_t<Observer>::kDifferentiating;
  const SurfaceHit& hit = path.hit;
  Pcg32& rng = path.rng;
  const Vec3 dir = path.dir;
  const bool frontFacing = hit.ng.dot(dir) < 0.0f;
  ShadingFrame frame(frontFacing ? hit.ns : Vec3(-hit.ns));  // two-sided BSDF: frame on the viewer's side
  const Vec3 wo = frame.toLocal(-dir);
  obs.vertex(depth, hit, frame, wo, path.beta);

  // Emission reached by the camera ray or by BSDF sampling from the previous vertex.
  const Color le = emittedRadiance(scope.emission(depth - 1), hit, dir);
  if ((le != 0.0f).any() || (kDifferentiating && frontFacing)) {
    float mis = 1.0f;
    if (depth > 0) {
      const float pdfLight = lights.pdfArea(hit.object) * hit.t * hit.t / std::abs(hit.ng.dot(dir));
      mis = powerHeuristic(path.prevPdf, pdfLight);
    }
    obs.emission(depth, hit, mis, le);
    path.L += path.beta * mis * le;
  }
  if (depth >= settings.maxDepth) {
    path.alive = false;
    return;
  }

  const bool frozen = &scope.bsdf(depth) != scope.sampling;  // evaluate with other parameters
  const BsdfParams sampleParams = bsdfParamsAt(*scope.sampling, hit);
  const BsdfParams evalParams = frozen ? bsdfParamsAt(scope.bsdf(depth), hit) : sampleParams;
  const VertexBsdf bsdf(sampleParams, wo);
  // Next-event estimation.
  if (const auto& ls = path.light) {
    Vec3 toLight = ls->hit.p - hit.p;
    const float dist2 = toLight.squaredNorm();
    const float dist = std::sqrt(dist2);
    toLight /= dist;
    const float cosLight = -ls->hit.ng.dot(toLight);
    const Vec3 wi = frame.toLocal(toLight);
    if (cosLight > 0.0f && wi.z() > 0.0f && dist > 0.0f) {
      const Color leLight = scope.emission(depth).emissionAt(ls->hit.object, ls->hit.uv);
      const BsdfEval sampled = bsdf.eval(wi, kBsdfValue | kBsdfPdf);
      const Color f = frozen ? evalBsdf(evalParams, wo, wi).f : sampled.f;
      if ((leLight != 0.0f).any() && (f.maxCoeff() > 0.0f || kDifferentiating)) {
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
          obs.nee(depth, wi, f, wi.z(), scale, leLight, ls->hit);
          path.L += path.beta * f * (wi.z() * scale) * leLight;
        }
      }
    }
  }

  // BSDF sampling.
  path.alive = false;
  const float uLobe = rng.next1D();
  const Vec2 uDir = rng.next2D();
  const auto bs = bsdf.sample(uLobe, uDir);
  if (!bs) return;
  const Color f = frozen ? evalBsdf(evalParams, wo, bs->wi).f : bs->f;
  float survival = 1.0f;
  path.betaSampling *= bs->weight;
  if (settings.russianRoulette && depth + 1 >= settings.rouletteDepth) {
    survival = std::clamp(path.betaSampling.maxCoeff(), 0.05f, 0.95f);
    if (rng.next1D() >= survival) return;
    path.betaSampling /= survival;
  }
  obs.scatter(depth, bs->wi, f, bs->wi.z(), bs->pdf, survival);
  path.beta *= f * (bs->wi.z() / (bs->pdf * survival));
  if (path.beta.maxCoeff() <= 0.0f && !kDifferentiating) return;
  path.dir = frame.toWorld(bs->wi);
  path.origin = Scene::offsetOrigin(hit, path.dir);
  path.prevPdf = bs->pdf;
  path.alive = true;
}

// Traces a wavefront of paths one bounce at a time, in phases over every live path: its ray
// traverses the BVH (prefetching the hit's face record); the hit's attributes are read (its albedo
// and emission texels prefetched), its light numbers drawn and its emitter chosen (the alias bin
// of the emitter's triangles prefetched); the light triangle is picked (its face record
// prefetched); the light point is formed (its emission texels prefetched); the vertex is shaded.
// Between issuing a load and using it lies the work of the other paths, so the dependent cache
// misses of one path overlap (a path at a time, each miss stalls it). Each path's arithmetic and
// random numbers are exactly those of tracing it alone, so results do not depend on the
// wavefront's width. observerOf(i) is path i's observer.
template <class ObserverOf>
void tracePaths(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                const PathSettings& settings, std::span<PathSlot> paths, ObserverOf&& observerOf) {
  for (int depth = 0;; ++depth) {
    bool any = false;
    for (size_t i = 0; i < paths.size(); ++i) {
      PathSlot& p = paths[i];
      if (!p.alive) continue;
      p.next = scene.traverse(p.origin, p.dir);
      observerOf(i).traced(p.origin, p.dir, INFINITY, false);
      p.alive = p.next.found();
      any |= p.alive;
    }
    if (!any) return;
    // A vertex below the maximum depth samples a light: its numbers are drawn here, before the
    // vertex's other draws, and the light point's chain of loads (alias bin and triangle, face
    // record, emission texels) is started one phase ahead of each use.
    const bool nee = depth < settings.maxDepth;
    for (PathSlot& p : paths) {
      if (!p.alive) continue;
      p.hit = scene.surfaceAt(p.next, p.origin, p.dir);
      if (depth == 0 && p.firstHit) *p.firstHit = p.hit;
      scope.sampling->prefetchAlbedo(p.hit.object, p.hit.uv);
      scope.emission(depth - 1).prefetchEmission(p.hit.object, p.hit.uv);
      p.light.reset();
      if (!nee) continue;
      const float uLightObject = p.rng.next1D();
      p.uLightTriangle = p.rng.next1D();
      p.uLightPoint = p.rng.next2D();
      if (!lights.empty()) p.lightPick = lights.pickEmitter(uLightObject, p.uLightTriangle);
    }
    if (nee && !lights.empty()) {
      for (PathSlot& p : paths)
        if (p.alive) p.lightPick = lights.pickTriangle(p.lightPick, p.uLightTriangle);
      const Appearance& emission = scope.emission(depth);
      for (PathSlot& p : paths) {
        if (!p.alive) continue;
        p.light = lights.sampleAt(p.lightPick, p.uLightPoint);
        emission.prefetchEmission(p.light->hit.object, p.light->hit.uv);
      }
    }
    for (size_t i = 0; i < paths.size(); ++i)
      if (paths[i].alive) shadeVertex(scene, lights, scope, settings, depth, paths[i], observerOf(i));
  }
}

// Calls waveOf(b, e) for consecutive sub-ranges of [begin, end) at most `width` long.
template <typename F>
void forEachWave(size_t begin, size_t end, size_t width, F&& waveOf) {
  for (size_t b = begin; b < end; b += width) waveOf(b, std::min(end, b + width));
}

// One path alone (a wavefront of one).
template <class Observer = NullPathObserver>
Color tracePath(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                const PathSettings& settings, Vec3 origin, Vec3 dir, Pcg32& rng, Observer&& obs = Observer{},
                SurfaceHit* firstHit = nullptr) {
  PathSlot path(origin, dir, rng, firstHit);
  tracePaths(
      scene, lights, scope, settings, std::span<PathSlot>(&path, 1), [&](size_t) -> auto& { return obs; });
  rng = path.rng;
  return path.L;
}

}  // namespace relume
