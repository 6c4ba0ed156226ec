// Two-pass radiance-cached adjoint solver. Pass 1 (primal, seed s1) estimates each ray's radiance
// and keeps only delta_j = dLoss/dI_hat_j. Pass 2 (adjoint, seed s2) traces each path once,
// caching a fixed-size record per vertex in a per-thread buffer (a wavefront of paths, as many as
// fit its bound), then sweeps each path backwards: the radiance arriving at every vertex is
// accumulated as a suffix (never subtracted from a total), and delta_j x derivative is scattered
// onto the parameters. Memory: O(batch) for delta + O(threads x kWaveRecordBytes) for records.
#pragma once
#include <array>
#include <functional>
#include <string_view>
#include <vector>

#include "adjoint/loss.h"
#include "core/enum_names.h"
#include "params/parameters.h"
#include "render/path_tracer.h"

namespace relume {

enum class GradientMode { Direct, Full };          // Direct: parameters at the first vertex only
enum class EmitterGradients { Strict, AllDepth };  // with Direct: emitters reached from x0 only, or any
enum class Pairing { Decorrelated, Crossfit, Reuse };

template <>
struct EnumNames<GradientMode> {
  static constexpr std::array<std::pair<GradientMode, std::string_view>, 2> values{
      {{GradientMode::Direct, "direct"}, {GradientMode::Full, "full"}}};
};
template <>
struct EnumNames<EmitterGradients> {
  static constexpr std::array<std::pair<EmitterGradients, std::string_view>, 2> values{
      {{EmitterGradients::Strict, "strict"}, {EmitterGradients::AllDepth, "all-depth"}}};
};
template <>
struct EnumNames<Pairing> {
  static constexpr std::array<std::pair<Pairing, std::string_view>, 3> values{
      {{Pairing::Decorrelated, "decorrelated"}, {Pairing::Crossfit, "crossfit"}, {Pairing::Reuse, "reuse"}}};
};

struct AdjointSettings {
  GradientMode mode = GradientMode::Direct;
  EmitterGradients emitters = EmitterGradients::Strict;
  Pairing pairing = Pairing::Decorrelated;
  PathSettings path;
  ParamMask mask;
  uint64_t seed = 0;
  // Which terms a mode differentiates, as an AppearanceScope would perturb them.
  bool bsdfGradientAt(int depth) const { return mode == GradientMode::Full || depth == 0; }
  bool emissionGradientFrom(int fromVertex) const {
    return mode == GradientMode::Full || emitters == EmitterGradients::AllDepth || fromVertex <= 0;
  }
  // Path vertices of a ray whose terms may splat texels (Gradients::accumulate bounds its logs by it).
  size_t splatVertices() const {
    return mode == GradientMode::Full || emitters == EmitterGradients::AllDepth ? static_cast<size_t>(path.maxDepth + 1)
                                                                                : 1;
  }
};

struct PassTimes {
  double primal = 0, loss = 0, adjoint = 0;
};

struct GradientResult {
  double loss = 0;  // estimate of the batch loss (mean over rays)
  PassTimes times;
};

// Seeds of the two independent samples of ray j in iteration `iteration`.
uint64_t primalSeed(const AdjointSettings& s, uint64_t iteration, size_t ray);
uint64_t adjointSeed(const AdjointSettings& s, uint64_t iteration, size_t ray);

// Radiance estimate of every ray (non-finite estimates become 0), ray j seeded by seedOf(j),
// each term evaluated with the appearance `scope` names.
std::vector<Color> traceRays(const Scene& scene, const LightSampler& lights, const AppearanceScope& scope,
                             const std::vector<BatchRay>& rays, const PathSettings& path,
                             const std::function<uint64_t(size_t)>& seedOf);

// Primal pass only: radiance estimates with seed s1; with `albedoSensitivity`, also each ray's
// dI/d(albedo) at its first vertex (the paths are then recorded, as in the adjoint pass).
// `ownChunksOnly`: over MPI ranks, only the rays of this rank's chunks are filled (the others are
// zero), which is all its adjoint pass reads (core/ranks.h).
std::vector<Color> primalPass(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                              const std::vector<BatchRay>& rays, const AdjointSettings& settings, uint64_t iteration,
                              std::vector<Color>* albedoSensitivity = nullptr, bool ownChunksOnly = false);

// Adjoint pass only: scatters sum_j delta_j . dr(I_hat_j)/dtheta (paths traced with seed s2 along
// the ray's adjointDirection(), r the ray's loss residual) into `grads`, and, when `grads` has
// albedo curvature storage, the Gauss-Newton curvature of the loss in the albedo texels under each ray's first vertex:
// the product of this pass's residual sensitivity and `primalSensitivity` (the primal's, times its residual slope;
// unbiased), or without it the square of this pass's own (inflated by its variance).
void adjointPass(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                 const std::vector<BatchRay>& rays, const std::vector<Color>& delta, const AdjointSettings& settings,
                 uint64_t iteration, Gradients& grads, const std::vector<Color>* primalSensitivity = nullptr);

// One iteration's gradient of the batch loss under settings.pairing. `grads` is accumulated into
// (clear it first) and combined on return. `estimates`, when given, receives each ray's radiance
// estimate before its gain (the mean of its two samples under crossfit; 0 where non-finite).
GradientResult computeGradients(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                                const std::vector<BatchRay>& rays, const AdjointSettings& settings, uint64_t iteration,
                                Gradients& grads, std::vector<Color>* estimates = nullptr);

// Bytes of one cached vertex record (reported by the profiler).
size_t adjointRecordBytes();
// Paths one thread traces together as a wavefront while recording them: as many as fit in
// kWaveRecordBytes of vertex records at this depth, at most kWavefrontWidth.
inline constexpr size_t kWaveRecordBytes = size_t{256} << 10;
size_t wavePaths(int maxDepth);
// Vertex records one thread holds: kRecordedWaves waves (crossfit records two) of wavePaths paths
// of up to depth + 1 vertices. Bounded, whatever the batch size or depth.
inline constexpr size_t kRecordedWaves = 2;
size_t adjointRecordBytesPerThread(int maxDepth);

}  // namespace relume
