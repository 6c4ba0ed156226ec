#include "adjoint/gradcheck.h"

#include <tbb/parallel_for.h>

#include <map>
#include <numeric>

#include "core/error.h"

namespace relume {
namespace {

// The appearance scope that perturbs exactly the terms `settings` differentiates.
AppearanceScope perturbedScope(const Appearance& base, const Appearance& perturbed, const AdjointSettings& s) {
  AppearanceScope scope = AppearanceScope::uniform(base);
  scope.bsdfFirst = &perturbed;
  scope.emissionFirst = &perturbed;
  if (s.mode == GradientMode::Full) scope.bsdfDeep = &perturbed;
  if (s.mode == GradientMode::Full || s.emitters == EmitterGradients::AllDepth) scope.emissionDeep = &perturbed;
  return scope;
}

std::vector<Eigen::Array3d> traceAll(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                                     const std::vector<BatchRay>& rays, const PathSettings& path,
                                     const std::function<uint64_t(size_t)>& seed) {
  std::vector<Eigen::Array3d> out;
  for (const Color& c : traceRays(scene, lights, scope, rays, path, seed)) out.push_back(c.cast<double>());
  return out;
}

// Radiance is linear in every emission, so any emission step is exact but for float rounding, which
// scales with the brightest radiance, i.e. the scene's largest emission: the step is relative to
// that, not to the parameter's own value (a dark wall's 0 gave a step below the rounding of ~1e4
// radiances at --emission-scale 1e4).
float emissionStepScale(const Appearance& a) {
  float largest = 1.0f;
  for (int o = 0; o < a.objectCount(); ++o) largest = std::max(largest, a.emission[o].maxCoeff());
  for (const Texture& t : a.emissionTextures)
    for (uint32_t i = 0; i < t.texelCount(); ++i) largest = std::max(largest, t.texel(i).maxCoeff());
  return largest;
}

float stepFor(const ParamRef& p, float eps, float emissionScale) {
  const bool emission = p.kind == ParamKind::Emission || p.kind == ParamKind::EmissionTexture;
  return emission ? eps * emissionScale : eps;
}

// Loss residual of each estimate, in double (the per-ray Jacobian weight applies to the loss).
Eigen::Array3d residualOf(const BatchRay& ray, const Eigen::Array3d& est) {
  return lossResidual(est.cast<float>(), ray).cast<double>();
}

// The scalar each pairing's per-sample estimator differentiates (see gradcheck.h), in double.
double sampleObjective(const std::vector<BatchRay>& rays, Pairing pairing, const std::vector<Eigen::Array3d>& a,
                       const std::vector<Eigen::Array3d>& b, const std::vector<Color>& deltaA,
                       const std::vector<Color>& deltaB) {
  double sum = 0;
  const double invN = 1.0 / rays.size();
  for (size_t j = 0; j < rays.size(); ++j) {
    switch (pairing) {
      case Pairing::Decorrelated:
        sum += (deltaA[j].cast<double>() * residualOf(rays[j], b[j])).sum();
        break;
      case Pairing::Crossfit:
        sum += 0.5 * ((deltaA[j].cast<double>() * residualOf(rays[j], b[j])).sum() +
                      (deltaB[j].cast<double>() * residualOf(rays[j], a[j])).sum());
        break;
      case Pairing::Reuse:
        sum += rays[j].weight * residualOf(rays[j], a[j]).square().sum() * invN;
        break;
    }
  }
  return sum;
}

// Unbiased estimate of the loss the adjoint differentiates, sum of E[r]^2, from two independent
// samples: r(a) r(b) (for an unclipped reference, (E[I_hat] - I)^2).
double productLoss(const std::vector<BatchRay>& rays, const std::vector<Eigen::Array3d>& a,
                   const std::vector<Eigen::Array3d>& b) {
  double sum = 0;
  for (size_t j = 0; j < rays.size(); ++j)
    sum += rays[j].weight * (residualOf(rays[j], a[j]) * residualOf(rays[j], b[j])).sum();
  return sum / rays.size();
}

std::vector<Color> deltas(const std::vector<BatchRay>& rays, const std::vector<Eigen::Array3d>& est) {
  std::vector<Color> d(rays.size());
  const float invN = 1.0f / rays.size();
  for (size_t j = 0; j < rays.size(); ++j) d[j] = rayLossDelta(est[j].cast<float>(), rays[j], rays[j].weight * invN);
  return d;
}

}  // namespace

std::vector<ParamRef> pickParameters(const Scene& scene, const Appearance& a, const std::vector<BatchRay>& rays,
                                     ParamKind kind, int count) {
  std::map<int, int> objectHits;
  std::map<uint32_t, int> texelHits;
  for (const BatchRay& r : rays) {
    const auto hit = scene.intersect(r.origin, r.dir);
    if (!hit) continue;
    ++objectHits[hit->object];
    if (a.usesTexture(hit->object)) {
      const TexelFootprint fp = a.albedo.footprint(hit->uv);
      ++texelHits[fp.index[std::max_element(fp.weight.begin(), fp.weight.end()) - fp.weight.begin()]];
    }
  }
  auto byCount = [](const auto& m) {
    std::vector<std::pair<int, typename std::decay_t<decltype(m)>::key_type>> v;
    for (const auto& [k, n] : m) v.push_back({-n, k});
    std::sort(v.begin(), v.end());
    return v;
  };
  std::vector<ParamRef> out;
  switch (kind) {
    case ParamKind::Albedo:
      for (const auto& [n, texel] : byCount(texelHits))
        if (static_cast<int>(out.size()) < count) out.push_back({kind, 0, texel, static_cast<int>(out.size() % 3)});
      break;
    case ParamKind::Roughness:
    case ParamKind::Specular:
      for (const auto& [n, object] : byCount(objectHits))
        if (static_cast<int>(out.size()) < count) out.push_back({kind, object, 0, 0});
      break;
    case ParamKind::Emission: {
      // Every constant-emission emitter (one channel each), then the most-seen non-emitter:
      // its gradient comes only through BSDF-sampled hits.
      for (int o = 0; o < a.objectCount(); ++o)
        if (a.isEmissive(o) && !a.emissionTexture(o) && static_cast<int>(out.size()) < count)
          out.push_back({kind, o, 0, static_cast<int>(out.size() % 3)});
      for (const auto& [n, object] : byCount(objectHits))
        if (!a.isEmissive(object)) {
          out.push_back({kind, object, 0, 1});
          break;
        }
      break;
    }
    case ParamKind::EmissionTexture:
      for (int o = 0; o < a.objectCount(); ++o)
        if (const Texture* t = a.emissionTexture(o); t && static_cast<int>(out.size()) < count) {
          const uint32_t centre = static_cast<uint32_t>((t->height / 2) * t->width + t->width / 2);
          out.push_back({kind, o, centre, static_cast<int>(out.size() % 3)});
        }
      break;
  }
  return out;
}

std::vector<double> meanAdjointGradient(const Scene& scene, const Appearance& appearance,
                                        const std::vector<BatchRay>& rays, const AdjointSettings& settings,
                                        const std::vector<ParamRef>& params, int batches) {
  const LightSampler lights(scene, appearance);
  std::vector<double> mean(params.size(), 0.0);
  Gradients g(appearance);
  for (int b = 0; b < batches; ++b) {
    g.clear();
    computeGradients(scene, appearance, lights, rays, settings, 1000 + b, g);
    for (size_t i = 0; i < params.size(); ++i) mean[i] += gradientValue(appearance, g, params[i]) / batches;
  }
  return mean;
}

GradcheckReport runGradcheck(const Scene& scene, const Appearance& base, const std::vector<BatchRay>& rays,
                             const GradcheckOptions& o) {
  GradcheckReport report;
  const AdjointSettings& s = o.settings;
  const LightSampler lights(scene, base);  // sampling stays with the unperturbed parameters
  std::vector<ParamRef> params;
  for (ParamKind k : o.kinds) {
    const auto picked = pickParameters(scene, base, rays, k, o.paramsPerKind);
    if (picked.empty()) fail("gradcheck: the batch reaches no parameter of kind '{}' in this scene", paramKindName(k));
    params.insert(params.end(), picked.begin(), picked.end());
  }
  auto seedA = [&](uint64_t it) { return [&s, it](size_t j) { return primalSeed(s, it, j); }; };
  auto seedB = [&](uint64_t it) { return [&s, it](size_t j) { return adjointSeed(s, it, j); }; };
  const AppearanceScope baseScope = AppearanceScope::uniform(base);
  const float emissionScale = emissionStepScale(base);

  // Central difference of `objective` with the parameter perturbed only where the mode differentiates.
  auto centralDifference = [&](const ParamRef& p, const std::function<double(const AppearanceScope&)>& objective) {
    Appearance plus = base, minus = base;
    const float h = stepFor(p, o.eps, emissionScale);
    paramValue(plus, p) += h;
    paramValue(minus, p) -= h;
    return (objective(perturbedScope(base, plus, s)) - objective(perturbedScope(base, minus, s))) / (2.0 * h);
  };

  if (o.level1) {
    const uint64_t it = 0;
    const auto a0 = traceAll(scene, lights, baseScope, rays, s.path, seedA(it));
    const auto b0 = traceAll(scene, lights, baseScope, rays, s.path, seedB(it));
    const std::vector<Color> dA = deltas(rays, a0), dB = deltas(rays, b0);
    Gradients g(base);
    computeGradients(scene, base, lights, rays, s, it, g);
    // Float rounding of each radiance estimate (~6e-8 relative) divided by the step bounds how
    // well any finite difference can resolve; the tolerance adds it to the relative 2e-3.
    double scale = 0;
    for (size_t j = 0; j < rays.size(); ++j)
      scale += (dA[j].abs().cast<double>() * (a0[j].abs() + b0[j].abs())).sum() + 1e-30;
    for (const ParamRef& p : params) {
      const double fd = centralDifference(p, [&](const AppearanceScope& scope) {
        const auto a =
            s.pairing == Pairing::Decorrelated ? a0 : traceAll(scene, lights, scope, rays, s.path, seedA(it));
        const auto b = s.pairing == Pairing::Reuse ? b0 : traceAll(scene, lights, scope, rays, s.path, seedB(it));
        return sampleObjective(rays, s.pairing, a, b, dA, dB);
      });
      GradcheckRow row{"sample", p, gradientValue(base, g, p), fd};
      const double floorAbs = 20 * 6e-8 * scale / stepFor(p, o.eps, emissionScale);
      row.error = std::abs(row.adjoint - fd) / std::max(std::abs(fd), 1e-12);
      row.pass = std::abs(row.adjoint - fd) <= o.level1Tolerance * std::abs(fd) + floorAbs;
      report.rows.push_back(row);
    }
  }

  if (o.level2) {
    const int n = std::max(2, o.batches);
    std::vector<std::vector<double>> diff(params.size()), adj(params.size()), fds(params.size());
    Gradients g(base);
    for (int b = 0; b < n; ++b) {
      const uint64_t it = 1 + b;
      g.clear();
      computeGradients(scene, base, lights, rays, s, it, g);
      for (size_t i = 0; i < params.size(); ++i) {
        const double fd = centralDifference(params[i], [&](const AppearanceScope& scope) {
          return productLoss(rays, traceAll(scene, lights, scope, rays, s.path, seedA(it)),
                             traceAll(scene, lights, scope, rays, s.path, seedB(it)));
        });
        adj[i].push_back(gradientValue(base, g, params[i]));
        fds[i].push_back(fd);
        diff[i].push_back(adj[i].back() - fd);
      }
    }
    auto mean = [](const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0) / v.size(); };
    for (size_t i = 0; i < params.size(); ++i) {
      const double md = mean(diff[i]);
      double var = 0;
      for (double d : diff[i]) var += (d - md) * (d - md);
      GradcheckRow row{"loss", params[i], mean(adj[i]), mean(fds[i])};
      row.stdError = std::sqrt(var / (n - 1) / n);
      row.error = std::abs(md) / std::max(row.stdError, 1e-300);  // in standard errors
      row.informational = s.pairing == Pairing::Reuse;
      // The finite difference itself is only exact to the level-1 tolerance; for crossfit, whose
      // estimator is exactly the derivative of the product loss, that floor is all that remains.
      row.pass = row.informational ||
                 std::abs(md) <= o.sigmas * row.stdError + o.level1Tolerance * std::abs(row.finiteDifference);
      report.rows.push_back(row);
    }
  }
  return report;
}

std::string directVersusFull(const Scene& scene, const Appearance& appearance, const std::vector<BatchRay>& rays,
                             const AdjointSettings& direct, const GradcheckReport& report, int batches) {
  std::vector<ParamRef> params;
  for (const GradcheckRow& r : report.rows)
    if (r.level == "loss") params.push_back(r.param);
  AdjointSettings full = direct;
  full.mode = GradientMode::Full;
  const auto gd = meanAdjointGradient(scene, appearance, rays, direct, params, batches);
  const auto gf = meanAdjointGradient(scene, appearance, rays, full, params, batches);
  std::string out = fmt::format("bias of direct vs full (mean over {} batches):\n{:<34} {:>14} {:>14} {:>10}\n",
                                batches, "parameter", "direct", "full", "rel diff");
  for (size_t i = 0; i < params.size(); ++i)
    out += fmt::format("{:<34} {:>14.6e} {:>14.6e} {:>9.1f}%\n", params[i].label(), gd[i], gf[i],
                       100.0 * std::abs(gd[i] - gf[i]) / std::max(std::abs(gf[i]), 1e-30));
  return out;
}

bool GradcheckReport::pass() const {
  return std::all_of(rows.begin(), rows.end(), [](const GradcheckRow& r) { return r.pass; });
}

std::string GradcheckReport::table() const {
  std::string out = fmt::format("{:<7} {:<34} {:>14} {:>14} {:>12} {}\n", "level", "parameter", "adjoint",
                                "finite diff", "error", "result");
  for (const GradcheckRow& r : rows) {
    const std::string err =
        r.level == "sample" ? fmt::format("{:.2e} rel", r.error) : fmt::format("{:.2f} se", r.error);
    out += fmt::format("{:<7} {:<34} {:>14.6e} {:>14.6e} {:>12} {}\n", r.level, r.param.label(), r.adjoint,
                       r.finiteDifference, err, r.informational ? "bias (reported)" : (r.pass ? "pass" : "FAIL"));
  }
  return out;
}

}  // namespace relume
