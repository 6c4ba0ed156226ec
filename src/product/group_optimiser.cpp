#include "product/group_optimiser.h"

#include <algorithm>
#include <cmath>

#include "core/check.h"
#include "optim/upsample.h"

namespace relume {

void GradientMasks::apply(ParamGroup& g, std::vector<float>& albedoCurvature,
                          std::span<const uint32_t> splattedAlbedo) const {
  switch (g.kind) {
    case ParamKind::Albedo:
      for (uint32_t t : splattedAlbedo) {
        const bool held = albedoHeld[space.objectOf(t, mesh)];
        if (!space.updatable[t] || held) std::fill_n(g.grads.begin() + 3 * static_cast<ptrdiff_t>(t), 3, 0.0f);
        if (held && !albedoCurvature.empty())
          std::fill_n(albedoCurvature.begin() + 3 * static_cast<ptrdiff_t>(t), 3, 0.0f);
      }
      break;
    case ParamKind::Roughness:
    case ParamKind::Specular:
      for (size_t o = 0; o < materialsFitted.size(); ++o)
        if (!materialsFitted[o]) g.grads[o] = 0.0f;
      break;
    case ParamKind::Emission:
      for (size_t o = 0; o < emits.size(); ++o)
        if (!emits[o]) g.grads[3 * o] = g.grads[3 * o + 1] = g.grads[3 * o + 2] = 0.0f;
      break;
    case ParamKind::EmissionTexture:
      break;
  }
}

AdamSettings GroupOptimiser::adamFor(const ParamGroup& g, float lrScale) const {
  AdamSettings s;
  s.masked = c_.maskedAdam;
  s.perEntrySteps = c_.perEntrySteps;
  switch (g.kind) {
    case ParamKind::Albedo:
      s.learningRate = c_.lrAlbedo;
      break;
    case ParamKind::Roughness:
      s.learningRate = c_.lrRoughness;
      break;
    case ParamKind::Specular:
      s.learningRate = c_.lrSpecular;
      break;
    case ParamKind::Emission:
    case ParamKind::EmissionTexture:
      s.learningRate = g.kind == ParamKind::Emission ? c_.lrEmission : c_.lrEmissionTexture;
      s.relativeFloor = c_.emissionFloor * radianceScale_;
      break;
  }
  s.learningRate *= lrScale;
  return s;
}

bool GroupOptimiser::step(ParamGroup& g, std::span<const float> albedoCurvature,
                          std::span<const uint32_t> splattedAlbedo, const Stage& st, int it) {
  CHECK(g.grads.size() == g.values.size());
  const float lrScale = st.settles.active(g.kind) ? st.settleScale(it, c_.lrFinalFraction) : 1.0f;
  if (g.kind == ParamKind::Albedo && newtonAlbedo()) {
    // No gradient clamp: the step is bounded by maxStep, and a bright outlier in the adjoint
    // sample inflates the curvature as much as the gradient.
    CHECK(albedoCurvature.size() == g.values.size());  // the stage allocated the curvature
    if (newton_.size() != g.values.size()) newton_ = GaussNewtonState(g.values.size(), c_.albedoStandardError);
    GaussNewtonSettings gn;
    gn.damping = c_.albedoDamping * lrScale;
    newton_.stepTexels(g.values, g.grads, albedoCurvature, g.lo, g.hi, gn, splattedAlbedo);
  } else {
    clampGradients(g.grads, c_.gradientClamp);
    auto [state, inserted] = adam_.try_emplace(g.name(), g.values.size());
    if (state->second.size() != g.values.size()) state->second = AdamState(g.values.size());
    state->second.step(g.values, g.grads, g.lo, g.hi, adamFor(g, lrScale), static_cast<uint32_t>(it + 1));
  }
  const bool perObjectMaterial = g.kind == ParamKind::Roughness || g.kind == ParamKind::Specular;
  const int from = st.averageFrom(g.kind, perObjectMaterial ? c_.materialPolyakFraction : c_.polyakFraction);
  if (it >= from) polyak_[g.name()].add(g.values);
  return it == from;
}

void GroupOptimiser::settle(std::span<ParamGroup> groups, const Stage& st) const {
  for (ParamGroup& g : groups)
    if (st.settles.active(g.kind))
      if (auto p = polyak_.find(g.name()); p != polyak_.end() && p->second.mean.size() == g.values.size())
        std::copy(p->second.mean.begin(), p->second.mean.end(), g.values.begin());
}

void GroupOptimiser::release(std::span<const ParamGroup> groups, const Stage& st) {
  for (const ParamGroup& g : groups)
    if (st.settles.active(g.kind)) adam_.erase(g.name()), polyak_.erase(g.name());
  if (st.settles.active(ParamKind::Albedo)) newton_ = GaussNewtonState();
}

namespace {

std::vector<uint16_t> upsampleSteps(const std::vector<uint16_t>& steps, const TexelSpace& from, const TexelSpace& to,
                                    const TriangleMesh& mesh) {
  const std::vector<float> up =
      upsampleTexels(std::vector<float>(steps.begin(), steps.end()), from.map, to.map, mesh, 3);
  std::vector<uint16_t> out(up.size());
  for (size_t i = 0; i < up.size(); ++i) out[i] = static_cast<uint16_t>(std::lround(up[i]));
  return out;
}

}  // namespace

// Each child texel receives about 1/f^2 of its parent's splat weight, so the sums of gradients
// and curvatures are divided by f^2 and Adam's second moment by f^4 (keeps m / sqrt(v), the
// step, the same).
void GroupOptimiser::upsampleAlbedo(const TexelSpace& from, const TexelSpace& to, const TriangleMesh& mesh) {
  const float f2 =
      static_cast<float>(to.resolution) / from.resolution * static_cast<float>(to.resolution) / from.resolution;
  if (newton_.size() > 0) {
    GaussNewtonState up;
    up.numerator = upsampleTexels(newton_.numerator, from.map, to.map, mesh, 3);
    up.curvature = upsampleTexels(newton_.curvature, from.map, to.map, mesh, 3);
    for (float& n : up.numerator) n /= f2;
    for (float& h : up.curvature) h /= f2;
    up.steps = upsampleSteps(newton_.steps, from, to, mesh);
    // The child's fit is its parent's, with its weights; its spread is measured again at the
    // finer resolution, where a texel's visits see less of the surface.
    if (newton_.tracksSpread()) {
      up.weightSquare = upsampleTexels(newton_.weightSquare, from.map, to.map, mesh, 3);
      up.residualSquare.assign(up.weightSquare.size(), -1.0f);
    }
    newton_ = std::move(up);
  }
  if (auto it = adam_.find("albedo"); it != adam_.end()) {
    AdamState& s = it->second;
    AdamState up;
    up.m = upsampleTexels(s.m, from.map, to.map, mesh, 3);
    up.v = upsampleTexels(s.v, from.map, to.map, mesh, 3);
    for (float& m : up.m) m /= f2;
    for (float& v : up.v) v /= f2 * f2;
    up.steps = upsampleSteps(s.steps, from, to, mesh);
    s = std::move(up);
  }
  polyak_.erase("albedo");
}

std::vector<float> GroupOptimiser::albedoStandardError(float bound) const {
  if (!newton_.tracksSpread()) return {};
  std::vector<float> e(newton_.size());
  for (size_t i = 0; i < e.size(); ++i) e[i] = newton_.standardError(i, bound);
  return e;
}

void GroupOptimiser::restartAfterLightChange() {
  newton_ = GaussNewtonState();
  adam_.erase("albedo");
  polyak_.erase("albedo");
  adam_.erase("emission");
}

void GroupOptimiser::serialise(CheckpointIo& io, std::span<ParamGroup> groups, size_t albedoEntries) {
  for (ParamGroup& g : groups) {
    const std::string name = g.name();
    if (io.optional(name + ".m", adam_.count(name) != 0)) {
      AdamState& s = io.writing() ? adam_.at(name) : (adam_[name] = AdamState(g.values.size()));
      io.arrayInPlace(name + ".m", s.m);
      io.arrayInPlace(name + ".v", s.v);
      io.arrayInPlace(name + ".steps", s.steps);
    }
    // Averages independently of Adam state: the albedo has none under the Gauss-Newton step.
    if (io.optional(name + ".mean", polyak_.count(name) != 0)) {
      PolyakAverage& p = polyak_[name];
      if (!io.writing()) p.mean.resize(g.values.size());
      io.arrayInPlace(name + ".mean", p.mean);
      io.single(name + ".count", p.count);
    }
  }
  if (io.optional("albedo.curvature", newton_.size() > 0) && (io.writing() || newtonAlbedo())) {
    if (!io.writing()) newton_ = GaussNewtonState(albedoEntries);
    io.arrayInPlace("albedo.numerator", newton_.numerator);
    io.arrayInPlace("albedo.curvature", newton_.curvature);
    io.arrayInPlace("albedo.curvature_steps", newton_.steps);
    if (io.optional("albedo.residual_square", newton_.tracksSpread())) {
      if (!io.writing()) newton_.residualSquare.resize(albedoEntries), newton_.weightSquare.resize(albedoEntries);
      io.arrayInPlace("albedo.residual_square", newton_.residualSquare);
      io.arrayInPlace("albedo.weight_square", newton_.weightSquare);
    }
  }
}

double GroupOptimiser::stateBytes() const {
  double bytes = 0;
  for (const auto& [name, a] : adam_)
    bytes += (a.m.size() + a.v.size()) * sizeof(float) + a.steps.size() * sizeof(uint16_t);
  return bytes +
         (newton_.numerator.size() + newton_.curvature.size() + newton_.residualSquare.size() +
          newton_.weightSquare.size()) *
             sizeof(float) +
         newton_.steps.size() * sizeof(uint16_t);
}

double GroupOptimiser::averageBytes() const {
  double bytes = 0;
  for (const auto& [name, p] : polyak_) bytes += p.mean.size() * sizeof(float);
  return bytes;
}

}  // namespace relume
