// The cameras of a capture folder, whichever form they come in: the nerfstudio transforms.json, or
// a COLMAP model (sparse/0/ or sparse/, its images in images/). Every command that reads a capture
// folder's cameras goes through here.
#pragma once
#include <filesystem>

#include "capture/transforms.h"

namespace relume {

// transforms.json if the folder has one (it wins over a COLMAP model, which is then ignored), else
// the COLMAP model in sparse/0/ or sparse/. Logs what was read; neither is a one-line relume::Error
// naming the folder and what was looked for.
Capture readCapture(const std::filesystem::path& folder);
// The capture's mesh: mesh.ply, else mesh.obj; neither is a one-line relume::Error naming the folder.
std::filesystem::path findCaptureMesh(const std::filesystem::path& folder);

}  // namespace relume
