#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "adjoint/solver.h"
#include "core/rng.h"
#include "lab/experiment.h"
#include "scenes/synth.h"

using namespace relume;

namespace {
BatchRay rayTo(const Color& reference, const ClipThresholds& clip = {}, const Color& gain = Color::Ones()) {
  BatchRay r{Vec3::Zero(), Vec3::UnitZ(), reference, clip};
  r.gain = gain;
  return r;
}
}  // namespace

TEST(Loss, OneSidedAtClipThresholds) {
  ClipThresholds clip{0.01f, 1.0f};
  const BatchRay saturated = rayTo(Color::Constant(1.2f), clip), dark = rayTo(Color::Constant(0.0f), clip);
  // Saturated reference: an estimate above vmax is not penalised; below, the residual is measured
  // from vmax (not from the unknown true value), so the loss is continuous at vmax.
  EXPECT_EQ(rayLoss(Color::Constant(1.5f), saturated), 0.0f);
  EXPECT_FLOAT_EQ(rayLoss(Color::Constant(0.5f), saturated), 3 * 0.25f);
  EXPECT_LT(rayLoss(Color::Constant(0.9999f), saturated), 1e-6f);
  EXPECT_LT(rayLossDelta(Color::Constant(0.5f), saturated, 1.0f)[0], 0.0f);
  EXPECT_EQ(lossResidualSlope(Color::Constant(1.5f), saturated)[0], 0.0f);
  EXPECT_EQ(lossResidualSlope(Color::Constant(0.5f), saturated)[0], 1.0f);
  // Dark reference below vmin: an estimate also below is not penalised, one above from vmin.
  EXPECT_EQ(rayLoss(Color::Constant(0.005f), dark), 0.0f);
  EXPECT_FLOAT_EQ(rayLoss(Color(0.31f, 0.01f, 0.01f), dark), 0.09f);
  EXPECT_FLOAT_EQ(rayLoss(Color(0.3f, 0.3f, 0.3f), rayTo(Color(0.1f, 0.3f, 0.5f))), 0.08f);
  EXPECT_TRUE(
      rayLossDelta(Color(0.3f, 0.3f, 0.3f), rayTo(Color(0.1f, 0.3f, 0.5f)), 0.5f).isApprox(Color(0.2f, 0.0f, -0.2f)));
  // Continuous where the estimate crosses a bound: a clipped reference is pulled to the bound.
  for (const auto& [reference, bound] : {std::pair{1.2f, 1.0f}, std::pair{0.0f, 0.01f}}) {
    EXPECT_LT(rayLoss(Color::Constant(bound - 1e-4f), rayTo(Color::Constant(reference), clip)), 1e-7f);
    EXPECT_LT(rayLoss(Color::Constant(bound + 1e-4f), rayTo(Color::Constant(reference), clip)), 1e-7f);
  }
}

// The frame's gain scales the prediction: r = g x estimate - reference, dr/d estimate = g, and the
// clip thresholds bound g x estimate (the frame's values), not the estimate.
TEST(Loss, TheFrameGainScalesThePrediction) {
  const Color gain(2.0f, 1.0f, 0.5f);
  const BatchRay ray = rayTo(Color(1.0f, 1.0f, 1.0f), {}, gain);
  EXPECT_TRUE(lossResidual(Color::Constant(0.5f), ray).isApprox(Color(0.0f, -0.5f, -0.75f)));
  EXPECT_TRUE(lossResidualSlope(Color::Constant(0.5f), ray).isApprox(gain));
  // Saturated at 1 in the frame: an estimate of 0.6 predicts 1.2 in red (above: no loss) and 0.3 in blue.
  const BatchRay clipped = rayTo(Color::Constant(1.0f), {0.0f, 1.0f}, gain);
  const Color r = lossResidual(Color::Constant(0.6f), clipped);
  EXPECT_EQ(r[0], 0.0f);
  EXPECT_FLOAT_EQ(r[2], 0.3f - 1.0f);
  EXPECT_EQ(lossResidualSlope(Color::Constant(0.6f), clipped)[0], 0.0f);
  EXPECT_EQ(lossResidualSlope(Color::Constant(0.6f), clipped)[2], 0.5f);
  // The delta is the derivative of the loss in the prediction; times the slope, in the estimate.
  const float eps = 1e-3f;
  const Color e = Color::Constant(0.7f);
  const float numeric = (rayLoss(e + Color(eps, 0, 0), ray) - rayLoss(e - Color(eps, 0, 0), ray)) / (2 * eps);
  EXPECT_NEAR((rayLossDelta(e, ray, 1.0f) * lossResidualSlope(e, ray))[0], numeric, 1e-3f);
}

namespace {
class AdjointPassTest : public ::testing::Test {
 protected:
  static ExperimentOptions options() {
    ExperimentOptions o;
    o.rays = 64;
    o.atlasResolution = 32;
    return o;
  }
  GradientExperiment e = makeGradientExperiment(SynthSceneKind::Cornell, options());
  Scene scene{e.truth.mesh};
  LightSampler lights{scene, e.current};
  AdjointSettings s;
};
}  // namespace

TEST_F(AdjointPassTest, TinyDeltasAreNotDroppedAndGradientIsLinear) {
  // Deltas are O(1/N): with a 2^20-ray batch they are ~1e-6 and must still be scattered.
  auto gradientFor = [&](float scale) {
    Gradients g(e.current);
    adjointPass(scene, e.current, lights, e.rays, std::vector<Color>(e.rays.size(), Color::Constant(scale)), s, 0, g);
    return g;
  };
  const Gradients small = gradientFor(1e-7f), large = gradientFor(1.0f);
  double norm = 0;
  for (size_t i = 0; i < small.objects.size(); ++i) {
    EXPECT_NEAR(small.objects[i] * 1e7, large.objects[i], 1e-4 * std::abs(large.objects[i]) + 1e-12);
    norm += std::abs(large.objects[i]);
  }
  EXPECT_GT(norm, 0.0);
}

TEST_F(AdjointPassTest, FrozenGroupsGetNoGradient) {
  s.mask.set(ParamKind::Roughness, false);
  s.mask.set(ParamKind::Albedo, false);
  Gradients g(e.current);
  computeGradients(scene, e.current, lights, e.rays, s, 0, g);
  for (int obj = 0; obj < e.current.objectCount(); ++obj) EXPECT_EQ(g.objects[g.roughnessSlot(obj)], 0.0);
  for (float v : g.albedo) EXPECT_EQ(v, 0.0f);
  double spec = 0;
  for (int obj = 0; obj < e.current.objectCount(); ++obj) spec += std::abs(g.objects[g.specularSlot(obj)]);
  EXPECT_GT(spec, 0.0);
}

TEST_F(AdjointPassTest, AlbedoCurvatureIsTheSquaredFirstVertexSensitivity) {
  // One ray at a time, delta = 1: the albedo gradient sums to the ray's sensitivity X = dI/da at
  // its first vertex (bilinear weights sum to 1), and the row-sum curvature to 2 X^2 (weight 2/N).
  s.mask = ParamMask::only({ParamKind::Albedo});
  int checked = 0;
  for (const BatchRay& ray : e.rays) {
    Gradients g(e.current, true);
    adjointPass(scene, e.current, lights, {ray}, {Color::Ones()}, s, 7, g);
    for (int c = 0; c < 3; ++c) {
      double gradient = 0, curvature = 0;
      for (size_t t = c; t < g.albedo.size(); t += 3) gradient += g.albedo[t], curvature += g.albedoCurvature[t];
      EXPECT_NEAR(curvature, 2 * gradient * gradient, 1e-4 * (curvature + 1e-6));
      EXPECT_GE(curvature, 0.0);
      checked += gradient > 0;
    }
  }
  EXPECT_GT(checked, 3 * 32);  // most rays see a lit, textured first vertex
  // With the primal's sensitivity X_p as partner the curvature is 2 X X_p.
  Gradients g(e.current, true);
  const std::vector<Color> partner = {Color(0.5f, 1.0f, 2.0f)};
  adjointPass(scene, e.current, lights, {e.rays[0]}, {Color::Ones()}, s, 7, g, &partner);
  for (int c = 0; c < 3; ++c) {
    double gradient = 0, curvature = 0;
    for (size_t t = c; t < g.albedo.size(); t += 3) gradient += g.albedo[t], curvature += g.albedoCurvature[t];
    EXPECT_NEAR(curvature, 2 * gradient * partner[0][c], 1e-4 * (std::abs(curvature) + 1e-6));
  }
  Gradients none(e.current);  // without curvature storage nothing is accumulated
  computeGradients(scene, e.current, lights, e.rays, s, 0, none);
  EXPECT_TRUE(none.albedoCurvature.empty());
}

TEST_F(AdjointPassTest, PrimalSensitivityEstimatesWhatTheAdjointDifferentiates) {
  // Over independent seeds, the primal pass's first-vertex albedo sensitivity and the adjoint
  // pass's albedo gradient at delta = 1 estimate the same sum over rays of dI/d(albedo).
  s.mask = ParamMask::only({ParamKind::Albedo});
  const int n = 200;
  Color sumP = Color::Zero(), sumA = Color::Zero(), sqP = Color::Zero(), sqA = Color::Zero();
  for (int it = 0; it < n; ++it) {
    std::vector<Color> x;
    primalPass(scene, e.current, lights, e.rays, s, it, &x);
    Color p = Color::Zero();
    for (const Color& v : x) p += v;
    Gradients g(e.current);
    adjointPass(scene, e.current, lights, e.rays, std::vector<Color>(e.rays.size(), Color::Ones()), s, it, g);
    Color a = Color::Zero();
    for (size_t t = 0; t < g.albedo.size(); ++t) a[t % 3] += g.albedo[t];
    sumP += p, sumA += a, sqP += p.square(), sqA += a.square();
  }
  for (int c = 0; c < 3; ++c) {
    const double mp = sumP[c] / n, ma = sumA[c] / n;
    const double se = std::sqrt((sqP[c] / n - mp * mp + sqA[c] / n - ma * ma) / n);
    EXPECT_GT(mp, 0.0);
    EXPECT_NEAR(mp, ma, 4 * se + 1e-6) << "channel " << c;
  }
}

TEST_F(AdjointPassTest, AdjointPassFollowsTheRaysAdjointDirection) {
  // Direct gradients of specular land on the adjoint path's first surface only: a ray whose
  // adjoint direction is another ray's gets exactly that ray's gradient (same seed, same delta).
  s.mask = ParamMask::only({ParamKind::Specular});
  auto gradientOf = [&](const BatchRay& ray) {
    Gradients g(e.current);
    adjointPass(scene, e.current, lights, {ray}, {Color::Ones()}, s, 3, g);
    return g.objects;
  };
  const auto firstObject = [&](const Vec3& o, const Vec3& d) { return scene.intersect(o, d)->object; };
  const BatchRay& a = e.rays[0];
  size_t other = 1;  // a ray from the same camera to another object
  while (other < e.rays.size() &&
         (e.rays[other].origin != a.origin || firstObject(a.origin, e.rays[other].dir) == firstObject(a.origin, a.dir)))
    ++other;
  ASSERT_LT(other, e.rays.size());
  BatchRay split = a, along = a;
  split.adjointDir = along.dir = e.rays[other].dir;
  EXPECT_EQ(gradientOf(split), gradientOf(along));
  EXPECT_NE(gradientOf(split), gradientOf(a));
  EXPECT_EQ(a.adjointDirection(), a.dir);  // the experiment's rays are point rays: one direction
}

TEST(GradientSums, AreBitIdenticalAtAnyThreadCount) {
  // Every buffer (albedo, its curvature, emission texels, per-object scalars) and the loss come out
  // the same whichever thread traced which ray: a fit is reproducible on any machine. 17,000 rays
  // span two sub-batches of splat logs; every vertex differentiated, every pairing.
  for (const bool textured : {false, true}) {
    ExperimentOptions o;
    o.rays = 17000;
    o.referenceSpp = 1;
    o.atlasResolution = 32;
    o.emissionTextures = textured;
    const GradientExperiment e = makeGradientExperiment(SynthSceneKind::Cornell, o);
    const Scene scene{e.truth.mesh};
    const LightSampler lights{scene, e.current};
    for (const Pairing pairing : {Pairing::Decorrelated, Pairing::Crossfit, Pairing::Reuse}) {
      SCOPED_TRACE(std::string(enumName(pairing)) + (textured ? ", emission textures" : ""));
      AdjointSettings s;
      s.mode = GradientMode::Full;
      s.pairing = pairing;
      auto gradientsAt = [&](int threads) {
        Gradients g(e.current, true);
        double loss = 0;
        tbb::task_arena(threads).execute(
            [&] { loss = computeGradients(scene, e.current, lights, e.rays, s, 3, g).loss; });
        return std::pair{std::move(g), loss};
      };
      const auto [one, lossOne] = gradientsAt(1);
      auto magnitude = [](const std::vector<float>& v) {
        double m = 0;
        for (float x : v) m += std::abs(x);
        return m;
      };
      // Every buffer compared below holds gradients (an all-zero one would compare equal vacuously).
      ASSERT_GT(magnitude(one.albedo), 0.0);
      ASSERT_GT(magnitude(one.albedoCurvature), 0.0);
      ASSERT_GT(magnitude(one.objects), 0.0);
      if (textured) {
        ASSERT_GT(magnitude(one.emissionTexture.at(0)), 0.0);
      }
      for (const int threads : {2, 3}) {
        const auto [many, lossMany] = gradientsAt(threads);
        EXPECT_EQ(lossOne, lossMany) << threads << " threads";
        EXPECT_TRUE(one.albedo == many.albedo) << threads << " threads";
        EXPECT_TRUE(one.albedoCurvature == many.albedoCurvature) << threads << " threads";
        EXPECT_TRUE(one.emissionTexture == many.emissionTexture) << threads << " threads";
        EXPECT_TRUE(one.objects == many.objects) << threads << " threads";
      }
    }
  }
}

TEST(GradientSums, SubBatchesShrinkWithTheSplattingVerticesAndSumTheSame) {
  // A ray that splats at every vertex of a deep path fills the logs depth times faster: the
  // sub-batch shrinks with the vertices that splat (bounded logs), and the sums do not change,
  // since a sub-batch sets when terms are applied, never their order.
  const SynthScene cornell = makeSynthScene(SynthSceneKind::Cornell, 64);
  const size_t texels = cornell.scene.appearance.albedo.texelCount();
  auto accumulated = [&](size_t splatVertices) {
    Gradients g(cornell.scene.appearance);
    g.accumulate(
        40000,
        [&](Gradients::Chunk& chunk, size_t begin, size_t end) {
          for (size_t ray = begin; ray < end; ++ray)
            for (uint64_t v = 0; v < 8; ++v) {
              const uint64_t h = hashTuple({ray, v});
              chunk.addAlbedo(static_cast<uint32_t>(h % texels), Color::Constant(1e-3f * static_cast<float>(h % 1000)));
            }
        },
        splatVertices);
    return std::pair{g.albedo, g.logBytes()};
  };
  const auto [shallow, shallowBytes] = accumulated(1);
  const auto [deep, deepBytes] = accumulated(8);
  EXPECT_TRUE(shallow == deep);
  EXPECT_LT(deepBytes, shallowBytes / 4) << shallowBytes << " vs " << deepBytes;
}

// AppearanceScope::bsdfSecond applies at x1 and nowhere else: with x1's BSDF black the paths end
// there (as with a maximum depth of 1), and with x1's as it is and x2's black they end at x2 (a
// maximum depth of 2), ray for ray.
TEST(TraceRays, TheSecondVertexBsdfAppliesThereAlone) {
  const SynthScene room = makeSynthScene(SynthSceneKind::Room, 64);
  const Scene scene(room.scene.mesh);
  const Appearance& a = room.scene.appearance;
  Appearance black = a;
  std::fill(black.albedoConstant.begin(), black.albedoConstant.end(), Color::Zero());
  std::fill(black.albedoFromTexture.begin(), black.albedoFromTexture.end(), 0);
  std::fill(black.specular.begin(), black.specular.end(), 0.0f);
  std::vector<BatchRay> rays;
  for (const Camera& cam : synthCameraPath(SynthSceneKind::Room, 2, 16, 12, 0.0))
    for (int y = 0; y < 12; ++y)
      for (int x = 0; x < 16; ++x)
        if (const auto dir = cam.rayDirection(Vec2(x + 0.5f, y + 0.5f))) {
          BatchRay r;
          r.origin = cam.position, r.dir = *dir, r.reference = Color::Zero();
          rays.push_back(r);
        }
  const LightSampler lights(scene, a);
  const auto trace = [&](const AppearanceScope& scope, int maxDepth) {
    PathSettings path;
    path.maxDepth = maxDepth;
    return traceRays(scene, lights, scope, rays, path, [](size_t j) { return hashTuple({j, 0x5eU}); });
  };
  AppearanceScope secondBlack = AppearanceScope::uniform(a);
  secondBlack.bsdfSecond = &black;
  AppearanceScope onlySecondKept{&a, &a, &black, &a, &a};
  onlySecondKept.bsdfSecond = &a;
  const std::vector<Color> one = trace(AppearanceScope::uniform(a), 1), two = trace(AppearanceScope::uniform(a), 2);
  const std::vector<Color> endAtX1 = trace(secondBlack, 5), endAtX2 = trace(onlySecondKept, 5);
  ASSERT_EQ(one.size(), rays.size());
  size_t differs = 0;
  for (size_t j = 0; j < rays.size(); ++j) {
    EXPECT_TRUE((endAtX1[j] == one[j]).all()) << "ray " << j << ": " << endAtX1[j].transpose() << " vs " << one[j].transpose();
    EXPECT_TRUE((endAtX2[j] == two[j]).all()) << "ray " << j << ": " << endAtX2[j].transpose() << " vs " << two[j].transpose();
    differs += (one[j] != two[j]).any();
  }
  EXPECT_GT(differs, rays.size() / 2) << "the second bounce must light most of these pixels";
}
