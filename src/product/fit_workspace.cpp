#include "product/fit_workspace.h"

#include <algorithm>
#include <cmath>

#include "capture/capture_folder.h"
#include "capture/photometric_consistency.h"
#include "core/error.h"
#include "io/file_system.h"
#include "io/image.h"
#include "scene/atlas.h"

namespace relume {
namespace fs = std::filesystem;

Workspace::Workspace(const fs::path& work) : dir(work) {
  const fs::path pj = work / "prepare.json";
  if (!pathExists(pj))
    fail("{}: no prepare.json; run `relume prepare CAPTURE --out {}` first", work.string(), work.string());
  prepare = readJson(pj);
  for (const char* f : {"atlas_mesh.ply", "frames.bin", "visibility.bin", "albedo_init.exr", "coverage.exr"})
    if (!pathExists(work / f)) fail("{}: missing {}; rerun `relume prepare`", work.string(), f);
  withJsonErrors(pj, [&] {
    const fs::path capture = prepare.at("capture").get<std::string>();
    Capture cap = readCapture(capture);
    frames = std::move(cap.frames);
    exactPoses = cap.exactPoses;
    kept = jsonIntegers<uint32_t>(prepare.at("phases").at("frames").at("kept"), 0, UINT32_MAX, pj.string(), "kept");
    resolutions = jsonIntegers<int>(prepare.at("resolutions"), 1, kMaxTextureResolution, pj.string(), "resolutions");
    if (resolutions.empty()) fail("{}: no resolutions; rerun `relume prepare`", pj.string());
    const Json objectNames = prepare["phases"]["atlas"].value("object_names", Json::object());
    for (const auto& [id, name] : objectNames.items())
      names.push_back(
          {static_cast<int>(jsonInteger(Json::parse(id, nullptr, false), 0, INT32_MAX, pj.string(), "object_names")),
           name.get<std::string>()});
    return 0;
  });
  mesh = loadMesh(work / "atlas_mesh.ply");
  scene = std::make_unique<Scene>(mesh);
  store = std::make_unique<FrameStore>(work / "frames.bin");
  if (store->frameCount() != frames.size())
    fail("{}: frames.bin has {} frames but the capture's cameras {}; rerun `relume prepare`", work.string(),
         store->frameCount(), frames.size());
  for (uint32_t k : kept)
    if (k >= frames.size()) fail("{}: prepare.json keeps frame {} of {}", pj.string(), k, frames.size());
  vis = VisibilityIndex::read(work / "visibility.bin");
  initResolution = vis.resolution;
  const Image cov = readImage(work / "coverage.exr");
  if (cov.width != initResolution || cov.height != initResolution)
    fail("{}: coverage.exr is {}x{}, expected {}^2", work.string(), cov.width, cov.height, initResolution);
  coverage.resize(static_cast<size_t>(initResolution) * initResolution);
  for (size_t t = 0; t < coverage.size(); ++t) coverage[t] = cov.rgb[3 * t];
  if (kept.empty()) fail("{}: prepare dropped every frame (see prepare.json)", work.string());
}

float Workspace::coverageOf(size_t t, int res) const {
  const int s = res / initResolution;
  const size_t x = (t % res) / s, y = (t / res) / s;
  return coverage[y * initResolution + x];
}

int Workspace::resolvedResolution(const Batch& batch) const {
  const Workspace& w = *this;
  std::vector<float> footprint;
  for (const BatchRay& r : batch.rays) {
    const auto hit = w.scene->intersect(r.origin, r.dir);
    if (!hit) continue;
    const Camera* cam = nullptr;
    for (uint32_t k : w.kept)
      if ((w.frames[k].camera.position - r.origin).squaredNorm() == 0.0f) cam = &w.frames[k].camera;
    if (!cam) continue;
    // Pixel footprint on the surface: distance / focal length, stretched by the obliquity.
    footprint.push_back(hit->t / cam->fx / std::max(0.2f, std::abs(hit->ng.dot(r.dir))));
  }
  const double texelsPerMetreInit =
      w.prepare["phases"]["atlas"].value("texels_per_metre", 0.0) * w.initResolution /
      w.prepare["phases"]["atlas"].value("gutter_resolution", AtlasOptions{}.gutterResolution);
  if (footprint.empty() || texelsPerMetreInit <= 0) return w.resolutions.back();
  std::nth_element(footprint.begin(), footprint.begin() + footprint.size() / 2, footprint.end());
  const double pixelMetres = footprint[footprint.size() / 2];
  for (int r : w.resolutions)
    if (1.0 / (texelsPerMetreInit * r / w.initResolution) <= pixelMetres) return r;
  return w.resolutions.back();
}

namespace {
// A texel space's resolution: at least the prepared one its coverage is looked up at.
int atLeastPrepared(const Workspace& w, int res) {
  if (res < w.initResolution)
    fail("texel space at {}^2: below the prepared resolution {}^2 (visibility.bin, coverage.exr)", res,
         w.initResolution);
  return res;
}
}  // namespace

TexelSpace::TexelSpace(const Workspace& w, int res, const std::vector<uint8_t>& excluded)
    : resolution(atLeastPrepared(w, res)), map(w.mesh, res), updatable(map.texelCount(), 0) {
  for (size_t t = 0; t < map.texelCount(); ++t) {
    if (!map.valid(t) || w.coverageOf(t, res) <= 0) continue;
    if (!excluded.empty() && excluded[w.mesh.faceObject[map.triangle(t)]]) continue;
    updatable[t] = 1;
    if (map.covered(t)) sampleable.push_back(static_cast<uint32_t>(t));
  }
  if (sampleable.empty()) fail("{}: no texel of the mesh was observed by any kept frame", w.dir.string());
}

std::vector<std::vector<uint32_t>> TexelSpace::sampleableByObject(const TriangleMesh& mesh, int objectCount) const {
  std::vector<std::vector<uint32_t>> texels(objectCount);
  for (uint32_t t : sampleable) texels[objectOf(t, mesh)].push_back(t);
  return texels;
}

Image Workspace::medianRadiance() const {
  const Image init = readImage(dir / "albedo_init.exr");
  if (init.width != initResolution || init.height != initResolution)
    fail("{}: albedo_init.exr is {}x{}, expected {}^2", dir.string(), init.width, init.height, initResolution);
  return init;
}

std::vector<Color> Workspace::consistencyGains() const {
  const fs::path file = dir / "frame_gains.json";
  if (!pathExists(file)) fail("{}: missing; rerun `relume prepare`", file.string());
  return readConsistencyGains(file, frames.size());
}

}  // namespace relume
