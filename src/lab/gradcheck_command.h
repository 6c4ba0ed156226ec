// `relume gradcheck`: adjoint gradients against central finite differences on a synthetic scene
// or the user's, printed as a table; exit code 1 on any failure.
#pragma once
#include <cmath>
#include <string>

#include "adjoint/solver.h"

namespace relume {

struct GradcheckRequest {
  std::string scene, cameras, synth = "room", param = "all", level = "both";
  GradientMode gradients = GradientMode::Direct;
  EmitterGradients emitters = EmitterGradients::Strict;
  Pairing pairing = Pairing::Decorrelated;
  int rays = 256, batches = 32, perKind = 3, maxDepth = kDefaultMaxDepth, atlas = 64;
  float eps = 1e-3f, emissionScale = 1.0f, clipHigh = INFINITY;
  bool roulette = false;
};

int runGradcheckCommand(const GradcheckRequest& a);

}  // namespace relume
