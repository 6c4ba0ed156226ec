// `relume render`: a scene rendered from every camera of a transforms.json, EXR + tone-mapped PNG
// per view and one EXR per AOV.
#pragma once
#include <filesystem>
#include <string>

#include "render/film.h"
#include "scene/appearance.h"

namespace relume {

struct RenderViewsOptions {
  RenderOptions render;
  std::string aovs;            // comma list
  std::filesystem::path edit;  // EDIT.json applied to the scene first (product/scene_edit.h); empty: none
};

RenderStats renderViews(const std::filesystem::path& sceneFile, const std::filesystem::path& cameras,
                        const std::filesystem::path& out, const RenderViewsOptions& options);

}  // namespace relume
