// The fit schedule the known-answer fit tests share: short stages on 64x48 captures.
#pragma once
#include "product/fit_config.h"

namespace relume {

inline FitConfig smallFitConfig() {
  FitConfig c;
  c.batchTexels = 2048;
  c.maxDepth = 4;
  c.emissionIterations = 80;
  c.materialIterations = 20;
  c.albedoPasses = 40;
  c.emissionTextureIterations = 0;
  c.checkpointEvery = 25;
  return c;
}

}  // namespace relume
