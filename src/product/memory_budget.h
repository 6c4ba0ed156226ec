// A fit within a memory budget (`relume fit --memory-budget 2G`, the memory_budget_mib key): the
// fit predicts its peak before any stage allocates, and takes the finest albedo resolution whose
// peak fits, or refuses up front, naming the figure it would need.
//
// Model: what the process holds when the fit plans (the workspace: mesh, Embree's BVH, face
// records, visibility index, libraries), plus the whole frame-cache mapping (file-backed: its pages
// count towards the resident set once read), the buffers every stage holds whatever its resolution
// (the path records of each thread, the batch), plus the bytes per texel of the finest albedo
// stage times its r^2 texels (every albedo array is a dense r x r texture): the albedo, the texel
// map and its flags, the step's state, the gradient buffers and the Polyak average; or, if larger,
// what the end of that stage holds while it smooths the albedo (its step state freed by then,
// product/group_optimiser.h). What the model leaves out (the light sampler's tables, emission
// textures at most emission_texture_resolution^2, the allocator's slack) is measured against it in
// docs/notes/2026-11-27-memory-budget.md.
#pragma once
#include <vector>

#include "io/json.h"
#include "product/fit_config.h"

namespace relume {

// Bytes per texel of a resolution-r albedo stage, r^2 texels of which `sampleableFraction` may be
// sampled, as the fit allocates them under config `c`.
struct TexelBytes {
  double albedo = 0, texelMap = 0, stepState = 0, gradients = 0, average = 0;
  double settling = 0;  // the end of the settling stage: the standard errors and the smoothing's arrays
  double stage() const { return albedo + texelMap + stepState + gradients + average; }
  // The most held per texel: in the stage, or at its end.
  double peak() const { return std::max(stage(), albedo + texelMap + settling); }
};
TexelBytes texelBytes(const FitConfig& c, double sampleableFraction);

struct MemoryEstimate {
  int resolution = 0;
  double fixedBytes = 0;  // whatever the resolution
  double texelBytes = 0;  // TexelBytes::peak() x resolution^2
  double peakBytes() const { return fixedBytes + texelBytes; }
};

struct MemoryPlan {
  // Of the budget, kept in reserve for what varies between runs of one fit (the allocator's
  // arenas, the light sampler's tables): the measured peaks differ by up to 4% from the prediction.
  static constexpr double kReserve = 0.05;
  double budgetBytes = 0;
  int resolution = 0;  // the finest that fits
  std::vector<MemoryEstimate> estimates;  // per candidate resolution, coarse to fine
  Json toJson() const;
};

// The finest of `resolutions` (coarse to fine) whose predicted peak is within `budgetBytes` (less
// its reserve), `fixedBytes` being held whatever the resolution, `frameCacheBytes` of them the
// frame cache's mapping. Throws relume::Error naming the figure the coarsest needs when none fits.
MemoryPlan planMemory(double budgetBytes, const std::vector<int>& resolutions, double fixedBytes,
                      double frameCacheBytes, const TexelBytes& perTexel);

}  // namespace relume
