// An iteration that carries no information must change nothing: masked Adam (every group but the
// albedo) and the Gauss-Newton albedo step leave values and state bit-identical.
#include "extremes.h"

#include "optim/adam.h"
#include "optim/gauss_newton.h"

using namespace relume;
using namespace relume::extremes;

namespace {

// The fit's optimisers over the Cornell experiment's groups, stepped with the solver's gradients
// (the albedo's over the texels the splats reached, as the fit does).
struct Optimisers {
  std::map<std::string, AdamState> adam;
  GaussNewtonState newton;

  void step(Appearance& a, Gradients& g, uint32_t iteration) {
    for (ParamGroup& group : paramGroups(a, &g)) {
      if (group.kind == ParamKind::Albedo) {
        if (newton.size() == 0) newton = GaussNewtonState(group.values.size());
        newton.stepTexels(group.values, group.grads, g.albedoCurvature, group.lo, group.hi, {},
                          g.splattedAlbedoTexels());
      } else {
        AdamSettings s;
        s.learningRate = 0.01f;
        s.relativeFloor = group.kind == ParamKind::Emission ? 0.02f : 0.0f;
        adam.try_emplace(group.name(), group.values.size())
            .first->second.step(group.values, group.grads, group.lo, group.hi, s, iteration);
      }
    }
  }
  bool operator==(const Optimisers& o) const {
    for (const auto& [name, s] : adam) {
      const AdamState& t = o.adam.at(name);
      if (s.m != t.m || s.v != t.v || s.steps != t.steps) return false;
    }
    return newton.numerator == o.newton.numerator && newton.curvature == o.newton.curvature &&
           newton.steps == o.newton.steps;
  }
};

std::vector<float> valuesOf(Appearance& a) {
  std::vector<float> v;
  for (const ParamGroup& g : paramGroups(a)) v.insert(v.end(), g.values.begin(), g.values.end());
  return v;
}

}  // namespace

TEST(ExtremeOptimiser, AZeroGradientIterationLeavesAdamAndGaussNewtonUntouched) {
  GradientExperiment e = cornell();
  const Scene scene(e.truth.mesh);
  AdjointSettings settings;
  settings.path.maxDepth = 4;
  Optimisers opt;
  // Three real iterations, so that moments, step counts and least-squares sums are nonzero.
  for (uint32_t it = 1; it <= 3; ++it) {
    const LightSampler lights(scene, e.current);
    Gradients g(e.current, true);
    computeGradients(scene, e.current, lights, e.rays, settings, it, g);
    opt.step(e.current, g, it);
  }
  ASSERT_GT(
      opt.newton.steps[std::max_element(opt.newton.steps.begin(), opt.newton.steps.end()) - opt.newton.steps.begin()],
      0);
  // A zero-gradient iteration from the solver itself: every reference dark below a threshold no
  // estimate reaches, so the one-sided loss and all its derivatives are exactly 0.
  for (BatchRay& r : e.rays) r.reference = Color::Zero(), r.clip.low = 1e6f;
  const LightSampler lights(scene, e.current);
  Gradients zero(e.current, true);
  computeGradients(scene, e.current, lights, e.rays, settings, 4, zero);
  const std::vector<float> before = valuesOf(e.current);
  const Optimisers state = opt;
  opt.step(e.current, zero, 4);
  // Bound: bit-identical (no entry had a gradient, so none is touched).
  EXPECT_EQ(valuesOf(e.current), before);
  EXPECT_TRUE(opt == state);
}

TEST(ExtremeOptimiser, ANonFiniteGradientEntryIsNoInformation) {
  // With the clamp off (gradient_clamp 0) nothing filters a NaN or Inf before the optimiser; one
  // such entry must not poison its moments, which would freeze the entry for good.
  std::vector<float> x = {0.5f, 0.5f, 0.5f};
  for (float bad : {NAN, INFINITY, -INFINITY}) {
    AdamState adam(3);
    AdamSettings s;
    adam.step(x, std::vector<float>{0.1f, 0.1f, 0.1f}, 0.0f, 1.0f, s, 1);
    const std::vector<float> xs = x, m = adam.m, v = adam.v;
    const std::vector<uint16_t> steps = adam.steps;
    EXPECT_EQ(adam.step(x, std::vector<float>{bad, 0.0f, 0.2f}, 0.0f, 1.0f, s, 2), 1u);
    EXPECT_EQ(x[0], xs[0]);
    EXPECT_EQ(adam.m[0], m[0]);
    EXPECT_EQ(adam.v[0], v[0]);
    EXPECT_EQ(adam.steps[0], steps[0]);
    EXPECT_NE(x[2], xs[2]);  // the finite entry still steps
    GaussNewtonState newton(1);
    std::vector<float> y = {0.5f};
    EXPECT_EQ(newton.step(y, std::vector<float>{bad}, std::vector<float>{1.0f}, 0.0f, 1.0f, {}), 0u);
    EXPECT_EQ(y[0], 0.5f);
    EXPECT_EQ(newton.steps[0], 0);
  }
}
