#include "product/export.h"

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "io/file_system.h"
#include "io/json.h"

namespace relume {

namespace fs = std::filesystem;

fs::path sceneFileOf(const fs::path& workOrScene) {
  if (isDirectory(workOrScene)) {
    const fs::path scene = workOrScene / "result" / "scene.json";
    if (!pathExists(scene))
      fail("{}: no result/scene.json (run `relume fit` first, or pass a scene.json)", workOrScene.string());
    return scene;
  }
  if (!pathExists(workOrScene)) fail("{}: no such work folder or scene.json", workOrScene.string());
  return workOrScene;
}

namespace {

Image imageOf(const Texture& t) {
  Image img(t.width, t.height);
  img.rgb = t.rgb;
  return img;
}

// Emission windows pasted into one image of their atlas's size (zero elsewhere).
Image emissionAtlas(const Appearance& a) {
  Image atlas;
  for (const Texture& t : a.emissionTextures) {
    if (atlas.rgb.empty()) atlas = Image(t.fullWidth, t.fullHeight);
    if (t.fullWidth != atlas.width || t.fullHeight != atlas.height)
      fail("emission textures live in atlases of different sizes ({}x{} and {}x{})", atlas.width, atlas.height,
           t.fullWidth, t.fullHeight);
    for (int y = 0; y < t.height; ++y)
      for (int x = 0; x < t.width; ++x)
        if (x + t.x0 < atlas.width && y + t.y0 < atlas.height) atlas.set(x + t.x0, y + t.y0, t.texel(y * t.width + x));
  }
  return atlas;
}

void writeTextures(const fs::path& dir, const ExportScene& s) {
  Json index = Json::object();
  if (!s.albedo.rgb.empty()) {
    writeExr(dir / "albedo.exr", s.albedo);
    writeSrgbPng(dir / "albedo_srgb8.png", s.albedo, 8);
    writeSrgbPng(dir / "albedo_srgb16.png", s.albedo, 16);
    index["albedo"] = {{"linear", "albedo.exr"}, {"srgb8", "albedo_srgb8.png"}, {"srgb16", "albedo_srgb16.png"}};
  }
  if (!s.emission.rgb.empty()) {
    // PNG holds [0,1]: the radiance divided by its peak, which is recorded.
    float peak = 0.0f;
    for (float v : s.emission.rgb) peak = std::max(peak, v);
    Image normalised = s.emission;
    for (float& v : normalised.rgb) v = peak > 0 ? v / peak : 0.0f;
    writeExr(dir / "emission.exr", s.emission);
    writeSrgbPng(dir / "emission_srgb8.png", normalised, 8);
    writeSrgbPng(dir / "emission_srgb16.png", normalised, 16);
    index["emission"] = {{"linear", "emission.exr"},
                         {"srgb8", "emission_srgb8.png"},
                         {"srgb16", "emission_srgb16.png"},
                         {"png_radiance_scale", peak}};
  }
  writeJson(dir / "textures.json", index);
}

}  // namespace

ExportScene exportSceneOf(const SceneDescription& scene) {
  const Appearance& a = scene.appearance;
  ExportScene out;
  out.mesh = scene.mesh.toData();
  out.albedo = a.albedo.empty() ? Image() : imageOf(a.albedo);
  out.emission = emissionAtlas(a);
  for (int o = 0; o < a.objectCount(); ++o) {
    ExportMaterial m;
    m.name = a.names[o];
    m.baseColor = a.albedoConstant[o];
    m.baseColorTextured = a.usesTexture(o);
    m.roughness = a.roughness[o];
    m.specular = a.specular[o];
    m.f90 = a.model == BsdfModel::PrincipledV1 ? 1.0f : a.specular[o];
    m.emission = a.emission[o];
    m.emissionTextured = a.emissionTexture(o) != nullptr;
    out.materials.push_back(m);
  }
  return out;
}

void exportScene(const fs::path& workOrScene, const ExportOptions& o) {
  if (o.gltf.empty() && o.mitsuba.empty() && o.textures.empty())
    fail("export: nothing to write (give --gltf, --mitsuba or --textures)");
  const fs::path file = sceneFileOf(workOrScene);
  const ExportScene s = exportSceneOf(loadSceneFile(file));
  if (!o.gltf.empty()) {
    writeGlb(o.gltf, s);
    spdlog::info("export: glTF {}", o.gltf.string());
  }
  if (!o.mitsuba.empty()) {
    writeMitsubaScene(o.mitsuba, s, o.maxDepth);
    spdlog::info("export: Mitsuba 3 scene {}", (o.mitsuba / "scene.xml").string());
  }
  if (!o.textures.empty()) {
    writeTextures(o.textures, s);
    spdlog::info("export: textures in {}", o.textures.string());
  }
}

}  // namespace relume
