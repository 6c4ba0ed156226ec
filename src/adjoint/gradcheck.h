// Adjoint gradients against central finite differences of the loss with common random numbers.
// Level 1 (per sample, frozen sampling): each ray's estimator is a smooth deterministic function
//   of the parameters once directions, pdfs, MIS weights, lobe/light choices and roulette come from
//   the unperturbed parameters; the adjoint must match its finite difference to ~1e-3.
// Level 2 (whole loss, statistical): over independent batches, the adjoint gradient and the
//   finite difference of an unbiased estimate of the true loss (product of two independent
//   samples) agree in expectation; accept within 4 standard errors of their paired difference.
// For `direct`, the finite difference perturbs the parameters only where `direct` differentiates
// them (first vertex; emitters reached from it), which is exactly what it computes.
#pragma once
#include <string>
#include <vector>

#include "adjoint/solver.h"

namespace relume {

struct GradcheckOptions {
  std::vector<ParamKind> kinds;
  AdjointSettings settings;
  int paramsPerKind = 3;
  float eps = 1e-3f;  // absolute for [0,1] parameters; for emission x the scene's largest emission (floor 1)
  int batches = 32;   // level 2
  bool level1 = true, level2 = true;
  double level1Tolerance = 2e-3;  // relative, on top of the float-rounding floor
  double sigmas = 4.0;            // level 2 acceptance
};

struct GradcheckRow {
  std::string level;  // "sample" or "loss"
  ParamRef param;
  double adjoint = 0, finiteDifference = 0, error = 0, stdError = 0;
  bool pass = true;
  bool informational = false;  // reuse's whole-loss bias: reported, not judged
};

struct GradcheckReport {
  std::vector<GradcheckRow> rows;
  bool pass() const;
  std::string table() const;
};

// Parameters of each kind that the batch actually reaches (most-hit objects, texels, emitters).
std::vector<ParamRef> pickParameters(const Scene& scene, const Appearance& appearance,
                                     const std::vector<BatchRay>& rays, ParamKind kind, int count);

GradcheckReport runGradcheck(const Scene& scene, const Appearance& appearance, const std::vector<BatchRay>& rays,
                             const GradcheckOptions& options);

// Mean adjoint gradient over `batches` batches for the given params (used to report direct vs full).
std::vector<double> meanAdjointGradient(const Scene& scene, const Appearance& appearance,
                                        const std::vector<BatchRay>& rays, const AdjointSettings& settings,
                                        const std::vector<ParamRef>& params, int batches);

// How far `direct` gradients are from `full` ones for the parameters of the report's whole-loss
// rows (mean over `batches`): the bias the paper's first-vertex gradients accept. A table.
std::string directVersusFull(const Scene& scene, const Appearance& appearance, const std::vector<BatchRay>& rays,
                             const AdjointSettings& direct, const GradcheckReport& report, int batches);

}  // namespace relume
