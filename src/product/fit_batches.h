// The rays of a fit iteration: a uniform batch of texels (texture-space sampler, or the image
// sampler for the ablation), plus in some stages texels drawn from a focus set: in the material
// stage the fitted objects' texels and their highlights, in the emission stages each
// light-source candidate's own texels. Each set draws from its own random stream.
#pragma once
#include <cstdint>
#include <vector>

#include "io/image.h"
#include "params/parameters.h"
#include "product/fit_config.h"
#include "product/fit_workspace.h"
#include "sampling/samplers.h"

namespace relume {

// The texels a stage draws more of (material_batch_texels, highlight_batch_texels,
// emission_batch_texels shared evenly between the candidates).
struct BatchFocus {
  std::vector<uint32_t> objects, highlights;
  std::vector<std::vector<uint32_t>> candidates;
};

class FitBatches {
 public:
  // With drop_disagreeing, reads prepare's median (albedo_init.exr) and the gains it divided by.
  FitBatches(const FitConfig& c, const Workspace& w);

  // The uniform batch of `iteration`, then the focused texels; every connection traced
  // samples_per_ray times.
  Batch sample(const TexelSpace& space, uint64_t iteration, RayFootprint footprint, const BatchFocus& focus = {}) const;

  // The material stage's focus: the sampleable texels of the objects whose materials are fitted
  // (`fitted`, per object), and those of them a frame sees with a light reflected. Each fitted
  // texel is connected to every frame that sees it (8 draws per texel: one is missed with
  // p ~ 3e-4). Depends on the geometry, the frames and the light sources only, so a resumed fit
  // finds the same texels.
  BatchFocus materialFocus(const TexelSpace& space, const std::vector<uint8_t>& fitted, const Appearance& appearance,
                           const std::vector<uint8_t>& emitter) const;
  // The emission stages' focus: each candidate light source's own texels. A uniform batch holds
  // an object's pixels in proportion to its area (a lamp of 6 texels among 75,000 is in one batch
  // out of two), so its emission would follow the walls it lights instead.
  BatchFocus emissionFocus(const TexelSpace& space, const std::vector<uint8_t>& emitter) const;

 private:
  // Leaves out of `b` the rays whose reference disagrees with its texel's median (drop_disagreeing).
  void dropDisagreeing(const TexelSpace& space, Batch& b) const;

  const FitConfig& c_;
  const Workspace& w_;
  Image median_;             // prepare's per-texel median radiance at the init resolution (drop_disagreeing)
  std::vector<Color> gains_;  // per frame, what prepare divided its pixels by before the median
};

// Whether connection `r` sees a light reflected: the mirror direction about the geometric
// normal, or one of four directions 10 degrees around it (a glossy lobe's width), reaches the
// front of an emitting light source. -1: the reference is masked or the ray hits nothing.
int8_t seesLightReflected(const Scene& scene, const Appearance& appearance, const std::vector<uint8_t>& emitter,
                          const BatchRay& r);

}  // namespace relume
