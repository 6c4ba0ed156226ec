// Unidirectional path tracer with next-event estimation and MIS (power heuristic).
// One kernel serves rendering and the adjoint solver: it reports each term of the estimate to an
// Observer (a no-op for rendering), and evaluates each term with the Appearance its
// AppearanceScope names, while every sampling decision (lobe choice, directions, pdfs, MIS
// weights, light choice, Russian roulette) uses `scope.sampling` only: sampling is detached.
#pragma once
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

template <class Observer = NullPathObserver>
Color tracePath(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                const PathSettings& settings, Vec3 origin, Vec3 dir, Pcg32& rng, Observer&& obs = Observer{},
                SurfaceHit* firstHit = nullptr) {
  Color L = Color::Zero(), beta = Color::Constant(1.0f), betaSampling = Color::Constant(1.0f);
  float prevPdf = 0.0f;
  for (int depth = 0;; ++depth) {
    const auto hit = scene.intersect(origin, dir);
    obs.traced(origin, dir, INFINITY, false);
    if (!hit) break;
    if (depth == 0 && firstHit) *firstHit = *hit;

    const bool frontFacing = hit->ng.dot(dir) < 0.0f;
    ShadingFrame frame(frontFacing ? hit->ns : Vec3(-hit->ns));  // two-sided BSDF: frame on the viewer's side
    const Vec3 wo = frame.toLocal(-dir);
    obs.vertex(depth, *hit, frame, wo, beta);

    // Emission reached by the camera ray or by BSDF sampling from the previous vertex.
    const Color le = emittedRadiance(scope.emission(depth - 1), *hit, dir);
    if ((le != 0.0f).any() || (std::decay_t<Observer>::kDifferentiating && frontFacing)) {
      float mis = 1.0f;
      if (depth > 0) {
        const float pdfLight = lights.pdfArea(hit->object) * hit->t * hit->t / std::abs(hit->ng.dot(dir));
        mis = powerHeuristic(prevPdf, pdfLight);
      }
      obs.emission(depth, *hit, mis, le);
      L += beta * mis * le;
    }
    if (depth >= settings.maxDepth) break;

    const bool frozen = &scope.bsdf(depth) != scope.sampling;  // evaluate with other parameters
    const BsdfParams sampleParams = bsdfParamsAt(*scope.sampling, *hit);
    const BsdfParams evalParams = frozen ? bsdfParamsAt(scope.bsdf(depth), *hit) : sampleParams;
    const VertexBsdf bsdf(sampleParams, wo);
    // Next-event estimation.
    const float uObject = rng.next1D(), uTri = rng.next1D();
    const Vec2 uPoint(rng.next1D(), rng.next1D());
    if (const auto ls = lights.sample(uObject, uTri, uPoint)) {
      Vec3 toLight = ls->hit.p - hit->p;
      const float dist2 = toLight.squaredNorm();
      const float dist = std::sqrt(dist2);
      toLight /= dist;
      const float cosLight = -ls->hit.ng.dot(toLight);
      const Vec3 wi = frame.toLocal(toLight);
      if (cosLight > 0.0f && wi.z() > 0.0f && dist > 0.0f) {
        const Color leLight = scope.emission(depth).emissionAt(ls->hit.object, ls->hit.uv);
        const BsdfEval sampled = bsdf.eval(wi, kBsdfValue | kBsdfPdf);
        const Color f = frozen ? evalBsdf(evalParams, wo, wi).f : sampled.f;
        if ((leLight != 0.0f).any() && (f.maxCoeff() > 0.0f || std::decay_t<Observer>::kDifferentiating)) {
          // Both ends are offset off their surfaces and the shadow ray joins them: a ray from the
          // offset origin along toLight would cross the light's own plane before a shortened tmax
          // wherever the light is seen at a slant, and count the light as its own occluder.
          const Vec3 o = Scene::offsetOrigin(*hit, toLight);
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
            L += beta * f * (wi.z() * scale) * leLight;
          }
        }
      }
    }

    // BSDF sampling.
    const float uLobe = rng.next1D();
    const Vec2 uDir(rng.next1D(), rng.next1D());
    const auto bs = bsdf.sample(uLobe, uDir);
    if (!bs) break;
    const Color f = frozen ? evalBsdf(evalParams, wo, bs->wi).f : bs->f;
    float survival = 1.0f;
    betaSampling *= bs->weight;
    if (settings.russianRoulette && depth + 1 >= settings.rouletteDepth) {
      survival = std::clamp(betaSampling.maxCoeff(), 0.05f, 0.95f);
      if (rng.next1D() >= survival) break;
      betaSampling /= survival;
    }
    obs.scatter(depth, bs->wi, f, bs->wi.z(), bs->pdf, survival);
    beta *= f * (bs->wi.z() / (bs->pdf * survival));
    if (beta.maxCoeff() <= 0.0f && !std::decay_t<Observer>::kDifferentiating) break;
    dir = frame.toWorld(bs->wi);
    origin = Scene::offsetOrigin(*hit, dir);
    prevPdf = bs->pdf;
  }
  return L;
}

}  // namespace relume
