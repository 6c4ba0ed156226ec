// Every fitted parameter of WORK/result/scene.json, group after group: two fits that end alike
// give equal vectors.
#pragma once
#include <filesystem>
#include <vector>

#include "params/parameters.h"
#include "scene/appearance.h"

namespace relume {

inline std::vector<float> fittedValues(const std::filesystem::path& work) {
  std::vector<float> v;
  SceneDescription fit = loadSceneFile(work / "result" / "scene.json");
  for (const ParamGroup& g : paramGroups(fit.appearance)) v.insert(v.end(), g.values.begin(), g.values.end());
  return v;
}

}  // namespace relume
