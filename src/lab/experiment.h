// Gradient experiments on synthetic scenes: a batch of camera rays with references rendered from
// the ground truth, and a "current" appearance perturbed away from it so the loss has a gradient.
#pragma once
#include "adjoint/solver.h"
#include "scenes/synth.h"

namespace relume {

struct GradientExperiment {
  SceneDescription truth;
  Appearance current;
  std::vector<BatchRay> rays;
};

struct ExperimentOptions {
  int rays = 256;
  int atlasResolution = 64;
  int referenceSpp = 4;
  int maxDepth = kDefaultMaxDepth;
  uint64_t seed = 7;
  bool emissionTextures = false;  // give emitters textured emission (for emission_tex gradients)
  float emissionScale = 1.0f;     // multiply every emitter (stress: very bright emitters)
  float clipHigh = INFINITY;      // reference clip threshold (one-sided loss above it)
};

GradientExperiment makeGradientExperiment(SynthSceneKind kind, const ExperimentOptions& options);
// The same for any scene, with rays aimed from `cameras`; emission textures (if requested) are
// added only when the scene has none.
GradientExperiment makeGradientExperiment(SceneDescription truth, const std::vector<Camera>& cameras,
                                          const ExperimentOptions& options);

// Batch rays from the cameras of a capture (random pixels); references rendered from `truth`.
std::vector<BatchRay> raysFromCameras(const Scene& scene, const Appearance& truth, const std::vector<Camera>& cameras,
                                      const ExperimentOptions& options);

// Deterministically moves every parameter away from `a` (inside its domain).
Appearance perturbAppearance(const Appearance& a, uint64_t seed);

}  // namespace relume
