// Edits applied to a scene before rendering (`relume render --edit EDIT.json`, schema in
// docs/user/edit-file.md): switch off or rescale emitters, change an object's material, add rectangular area
// lights and meshes with constant materials. Added geometry becomes new objects appended to the
// mesh (the BVH is rebuilt from it); the albedo atlas is untouched.
#pragma once
#include <filesystem>

#include "scene/appearance.h"

namespace relume {

// Applies EDIT.json to `scene`. Errors (unknown object, key or value out of its domain) are one
// line naming the file and the entry.
void applySceneEdit(SceneDescription& scene, const std::filesystem::path& editFile);

}  // namespace relume
