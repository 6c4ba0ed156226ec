#include "product/render_views.h"

#include <spdlog/spdlog.h>

#include "capture/transforms.h"
#include "core/error.h"
#include "product/scene_edit.h"

namespace relume {

namespace {
// An image with NaN or Inf pixels is wrong, and is refused rather than written.
void requireFinitePixels(const RenderResult& r, const std::filesystem::path& file) {
  if (const size_t bad = countNonFinitePixels(r.color))
    fail("{}: {} of {} rendered pixels are not finite ({} paths overflowed); not written", file.string(), bad,
         r.color.rgb.size() / 3, r.stats.nonFinitePaths);
}
}  // namespace

RenderStats renderViews(const std::filesystem::path& sceneFile, const std::filesystem::path& cameras,
                        const std::filesystem::path& out, const RenderViewsOptions& o) {
  SceneDescription desc = loadSceneFile(sceneFile);
  if (!o.edit.empty()) applySceneEdit(desc, o.edit);
  const Capture cap = readTransforms(cameras);
  const Scene scene(desc.mesh);
  const LightSampler lights(scene, desc.appearance);
  if (lights.empty()) spdlog::warn("{}: no emitters; images will be black", sceneFile.string());
  RenderOptions ro = o.render;
  ro.aovs = parseAovs(o.aovs);
  RenderStats total;
  for (const Frame& frame : cap.frames) {
    const RenderResult r = renderImage(scene, desc.appearance, lights, frame.camera, ro);
    const std::string stem = frame.image.stem().string();
    requireFinitePixels(r, out / (stem + ".exr"));
    writeExr(out / (stem + ".exr"), r.color);
    writePng(out / (stem + ".png"), r.color);
    for (size_t k = 0; k < r.aovs.size(); ++k)
      writeExr(out / fmt::format("{}_{}.exr", stem, aovName(ro.aovs[k])), r.aovs[k]);
    total.seconds += r.stats.seconds, total.paths += r.stats.paths, total.rays += r.stats.rays,
        total.nonFinitePaths += r.stats.nonFinitePaths;
  }
  spdlog::info("rendered {} views to {} in {:.1f}s: {:.3f} Mpaths/s, {:.2f} Mrays/s", cap.frames.size(), out.string(),
               total.seconds, total.paths / total.seconds * 1e-6, total.rays / total.seconds * 1e-6);
  if (total.nonFinitePaths)
    spdlog::warn("{} of {} paths carried non-finite radiance and were left out of their pixels", total.nonFinitePaths,
                 total.paths);
  return total;
}

}  // namespace relume
