#include "capture/capture_folder.h"

#include <spdlog/spdlog.h>

#include <optional>

#include "capture/colmap.h"
#include "core/error.h"
#include "io/file_system.h"

namespace relume {
namespace fs = std::filesystem;
namespace {

// COLMAP's mapper writes its first (usually only) model to sparse/0; some tools write sparse/ directly.
std::optional<fs::path> colmapModel(const fs::path& folder) {
  for (const fs::path& model : {folder / "sparse" / "0", folder / "sparse"})
    if (hasColmapModel(model)) return model;
  return std::nullopt;
}

}  // namespace

Capture readCapture(const fs::path& folder) {
  const fs::path transforms = folder / "transforms.json";
  const std::optional<fs::path> model = colmapModel(folder);
  if (fs::exists(transforms)) {
    if (model)
      spdlog::info("cameras: {} (the COLMAP model in {} is ignored)", transforms.string(), model->string());
    else
      spdlog::info("cameras: {}", transforms.string());
    return readTransforms(transforms);
  }
  if (!model)
    fail(
        "{}: no cameras: expected transforms.json, or a COLMAP model in sparse/0/ or sparse/ (cameras.txt + "
        "images.txt or cameras.bin + images.bin)",
        folder.string());
  const Capture cap = readColmap(*model, folder / "images");
  spdlog::info("cameras: COLMAP model {} + {}, {} frames", cap.files[0].string(), cap.files[1].string(),
               cap.frames.size());
  return cap;
}

fs::path findCaptureMesh(const fs::path& folder) {
  for (const char* name : {"mesh.ply", "mesh.obj"})
    if (pathExists(folder / name)) return folder / name;
  fail("{}: no mesh.ply or mesh.obj in the capture folder", folder.string());
}

}  // namespace relume
