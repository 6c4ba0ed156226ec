// `relume export`: a reconstruction (or any scene.json) as glTF 2.0 binary, a Mitsuba 3 scene and
// plain textures (linear EXR, sRGB PNG 8 and 16 bit), so it drops into other renderers as is.
#pragma once
#include <filesystem>

#include "io/export_scene.h"
#include "render/path_tracer.h"
#include "scene/appearance.h"

namespace relume {

// A work folder (its result/scene.json) or a scene.json; one-line error otherwise.
std::filesystem::path sceneFileOf(const std::filesystem::path& workOrScene);

// relume's appearance as exporter data: emission windows are placed into one atlas-sized image.
ExportScene exportSceneOf(const SceneDescription& scene);

struct ExportOptions {
  std::filesystem::path gltf;       // .glb file; empty: none
  std::filesystem::path mitsuba;    // folder; empty: none
  std::filesystem::path textures;   // folder; empty: none
  int maxDepth = kDefaultMaxDepth;  // written into the Mitsuba integrator
};

void exportScene(const std::filesystem::path& workOrScene, const ExportOptions& options);

}  // namespace relume
