#include "product/evaluate.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <optional>
#include <set>

#include "capture/frame_image.h"
#include "capture/transforms.h"
#include "core/error.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "scene/texel_map.h"

namespace relume {

Json ViewComparison::toJson() const {
  return {{"psnr", psnr}, {"msre", msre}, {"frame_psnr", framePsnr}, {"frame_msre", frameMsre}};
}

ImageScore scoreImage(const Image& estimate, const Image& reference, const std::string& what) {
  double se = 0, rel = 0;
  size_t n = 0;
  for (size_t i = 0; i < reference.rgb.size(); ++i) {
    const float ref = reference.rgb[i], est = estimate.rgb[i];
    if (ref < 0 || !std::isfinite(est)) continue;  // masked pixel
    const double d = linearToSrgb(std::clamp(est, 0.0f, 1.0f)) - linearToSrgb(std::clamp(ref, 0.0f, 1.0f));
    se += d * d;
    rel += double(est - ref) * (est - ref) / (double(ref) * ref + 1e-2);
    ++n;
  }
  if (n == 0) fail("{}: every pixel is masked", what);
  return {10.0 * std::log10(1.0 / std::max(se / n, 1e-12)), rel / n};
}

SplitRender renderSplit(const Scene& scene, const Appearance& appearance, const LightSampler& lights,
                        const Camera& camera, const RenderOptions& render) {
  RenderOptions first = render, second = render;
  first.spp = std::max(1, render.spp / 2), second.spp = std::max(1, render.spp - first.spp);
  first.seed = 2 * render.seed, second.seed = 2 * render.seed + 1;
  const Image a = renderImage(scene, appearance, lights, camera, first).color;
  const Image b = renderImage(scene, appearance, lights, camera, second).color;
  // Halves of n1 and n2 samples: mean = (n1 a + n2 b) / (n1 + n2) has variance s^2 / (n1 + n2);
  // (a - b) has s^2 (1/n1 + 1/n2), so k (a - b) with k = sqrt(n1 n2) / (n1 + n2) matches it.
  const float n1 = static_cast<float>(first.spp), n2 = static_cast<float>(second.spp);
  const float k = std::sqrt(n1 * n2) / (n1 + n2);
  SplitRender r{Image(a.width, a.height), Image(a.width, a.height)};
  for (size_t i = 0; i < a.rgb.size(); ++i) {
    r.mean.rgb[i] = (n1 * a.rgb[i] + n2 * b.rgb[i]) / (n1 + n2);
    r.noise.rgb[i] = k * (a.rgb[i] - b.rgb[i]);
  }
  return r;
}

double ViewError::beyondNoiseRms() const { return std::sqrt(std::max(0.0, errorRms * errorRms - noiseRms * noiseRms)); }

namespace {

// `difference(i)` and `noise(i)` of pixel channel i, averaged over the blocks where `reference` keeps pixels.
template <class Difference, class Noise>
ViewError viewError(const Image& reference, int block, const Difference& difference, const Noise& noise) {
  if (block < 1) fail("view error: block {} must be at least 1 pixel", block);
  const int W = (reference.width + block - 1) / block, H = (reference.height + block - 1) / block;
  ViewError v{Image(W, H), Image(W, H)};
  double errorSquares = 0, noiseSquares = 0;
  for (int by = 0; by < H; ++by)
    for (int bx = 0; bx < W; ++bx)
      for (int c = 0; c < 3; ++c) {
        double d = 0, n = 0, ref = 0;
        int kept = 0;
        for (int y = by * block; y < std::min((by + 1) * block, reference.height); ++y)
          for (int x = bx * block; x < std::min((bx + 1) * block, reference.width); ++x) {
            const size_t i = 3 * (static_cast<size_t>(y) * reference.width + x) + c;
            if (reference.rgb[i] < 0) continue;  // masked
            d += difference(i), n += noise(i), ref += reference.rgb[i];
            ++kept;
          }
        if (kept == 0) continue;
        const double e = std::abs(d / kept), en = std::abs(n / kept);
        const size_t o = 3 * (static_cast<size_t>(by) * W + bx) + c;
        v.error.rgb[o] = static_cast<float>(e), v.noise.rgb[o] = static_cast<float>(en);
        v.errorMean += e, v.noiseMean += en, errorSquares += e * e, noiseSquares += en * en,
            v.referenceMean += ref / kept;
        ++v.samples;
      }
  const double count = static_cast<double>(std::max<size_t>(v.samples, 1));
  v.errorMean /= count, v.noiseMean /= count, v.referenceMean /= count;
  v.errorRms = std::sqrt(errorSquares / count), v.noiseRms = std::sqrt(noiseSquares / count);
  return v;
}

}  // namespace

ViewError errorAgainstTruth(const SplitRender& fit, const SplitRender& truth, const Image& reference, int block) {
  return viewError(
      reference, block, [&](size_t i) { return fit.mean.rgb[i] - truth.mean.rgb[i]; },
      [&](size_t i) { return fit.noise.rgb[i] - truth.noise.rgb[i]; });
}

ViewError errorAgainstPhoto(const SplitRender& render, const Image& photo, int block) {
  return viewError(
      photo, block, [&](size_t i) { return render.mean.rgb[i] - photo.rgb[i]; },
      [&](size_t i) { return render.noise.rgb[i]; });
}

ViewComparison compareViews(const SceneDescription& desc, const std::filesystem::path& cameras,
                            const RenderOptions& render, const std::filesystem::path& out) {
  const Capture cap = readTransforms(cameras);
  const Scene scene(desc.mesh);
  const LightSampler lights(scene, desc.appearance);
  ViewComparison v;
  Progress progress("re-render", cap.frames.size());
  for (const Frame& frame : cap.frames) {
    const Image reference = loadFrameImage(frame);
    const RenderResult r = renderImage(scene, desc.appearance, lights, frame.camera, render);
    if (!out.empty()) {
      const std::string stem = frame.image.stem().string();
      writeExr(out / (stem + ".exr"), r.color);
      writePng(out / (stem + ".png"), r.color);
    }
    const ImageScore s = scoreImage(r.color, reference, frame.image.string());
    v.framePsnr.push_back(s.psnr);
    v.frameMsre.push_back(s.msre);
    progress.advance();
  }
  for (size_t i = 0; i < v.framePsnr.size(); ++i)
    v.psnr += v.framePsnr[i] / v.framePsnr.size(), v.msre += v.frameMsre[i] / v.frameMsre.size();
  return v;
}

Json TruthComparison::toJson() const {
  Json j = {{"albedo_texels", albedoTexels},       {"albedo_mae", albedoMae},
            {"albedo_psnr", albedoPsnr},           {"roughness_mae", roughnessMae},
            {"specular_mae", specularMae},         {"material_objects", materialObjects},
            {"roughness_mae_all", roughnessMaeAll}, {"specular_mae_all", specularMaeAll},
            {"opaque_objects", opaqueObjects},
            {"emitters_true", emittersTrue},       {"emitters_found", emittersFound},
            {"emitters_correct", emittersCorrect}, {"emission_rel_error", emissionRelError},
            {"albedo_psnr_8bit", albedoPsnr8},     {"roughness_psnr_8bit", roughnessPsnr8},
            {"emission_iou", emissionIou},         {"objects", perObject}};
  if (albedoStandardErrorRms >= 0)
    j["albedo_stderr_rms"] = albedoStandardErrorRms, j["albedo_within_2_stderr"] = albedoWithinTwoStandardErrors;
  return j;
}

TruthOptions truthOptionsFor(const std::filesystem::path& sceneFile) {
  TruthOptions o;
  const std::filesystem::path materials = sceneFile.parent_path() / "materials.json";
  if (!pathExists(materials)) return o;
  const Json m = readJson(materials);
  withJsonErrors(materials, [&] {
    for (const Json& obj : m.at("objects")) o.highlightObserved.push_back(obj.at("highlight_observed").get<bool>());
    return 0;
  });
  if (const std::filesystem::path e = sceneFile.parent_path() / "albedo_stderr.exr"; pathExists(e))
    o.albedoStandardError = readImage(e);
  return o;
}

namespace {
int srgb8(float linear) {
  return static_cast<int>(std::lround(std::clamp(linearToSrgb(std::max(linear, 0.0f)), 0.0f, 1.0f) * 255));
}
int unit8(float v) { return static_cast<int>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255)); }
double psnrOf(double sumSquares, size_t n) {
  return 10.0 * std::log10(1.0 / std::max(sumSquares / std::max<size_t>(n, 1), 1e-12));
}
}  // namespace

std::string differentTriangles(const TriangleMesh& fm, const TriangleMesh& tm) {
  if (fm.triangles.size() != tm.triangles.size())
    return fmt::format("the fitted mesh has {} triangles, the truth {}: they must be the same triangles",
                       fm.triangles.size(), tm.triangles.size());
  // The same triangles, each vertex within half the truth triangle's longest edge of its own: a
  // scan's noise (synth --imperfect mesh=...) moves vertices, a different mesh moves triangles.
  for (size_t f = 0; f < fm.triangles.size(); f += std::max<size_t>(1, fm.triangles.size() / 64)) {
    const auto& tt = tm.triangles[f];
    float longest = 0;
    for (int k = 0; k < 3; ++k)
      longest = std::max(longest, (tm.positions[tt[k]] - tm.positions[tt[(k + 1) % 3]]).norm());
    for (int k = 0; k < 3; ++k)
      if (!((fm.positions[fm.triangles[f][k]] - tm.positions[tt[k]]).norm() <= 1e-4f + 0.5f * longest))
        return fmt::format("triangle {} differs between the fitted and the truth mesh", f);
  }
  return "";
}

TexelUvs texelUvs(const TriangleMesh& fitMesh, const TriangleMesh& truthMesh, const TexelMap& map, size_t t) {
  const uint32_t tri = map.triangle(t);
  const Vec3 bc = map.barycentrics(fitMesh, t);
  TexelUvs uvs{Vec2::Zero(), Vec2::Zero()};
  for (int k = 0; k < 3; ++k) {
    if (truthMesh.hasUv()) uvs.truth += bc[k] * truthMesh.uvs[truthMesh.triangles[tri][k]];
    uvs.fit += bc[k] * fitMesh.uvs[fitMesh.triangles[tri][k]];
  }
  return uvs;
}

Image truthAlbedoInAtlas(const TriangleMesh& fitMesh, const SceneDescription& truth, int res) {
  if (const std::string why = differentTriangles(fitMesh, truth.mesh); !why.empty()) fail("{}", why);
  const TexelMap map(fitMesh, res);
  Image albedo(res, res);
  for (size_t t = 0; t < map.texelCount(); ++t)
    if (map.covered(t))
      albedo.set(static_cast<int>(t % res), static_cast<int>(t / res),
                 truth.appearance.albedoAt(truth.mesh.faceObject[map.triangle(t)],
                                           texelUvs(fitMesh, truth.mesh, map, t).truth));
  return albedo;
}

TruthComparison compareWithTruth(const SceneDescription& fit, const SceneDescription& truth, const Image& coverage,
                                 const TruthOptions& o, Image* truthAlbedo) {
  if (const std::string why = differentTriangles(fit.mesh, truth.mesh); !why.empty()) fail("eval: {}", why);
  const TriangleMesh& fm = fit.mesh;
  const TriangleMesh& tm = truth.mesh;
  TruthComparison c;
  const Appearance& fa = fit.appearance;
  const Appearance& ta = truth.appearance;
  // Albedo: every covered texel of the fit observed often enough, against the truth at its point.
  const int res = fa.albedo.width;
  const TexelMap map(fm, res);
  if (truthAlbedo) *truthAlbedo = Image(res, res);
  double abs = 0, sq = 0, sq8 = 0, roughSq8 = 0, seSq = 0;
  size_t emitBoth = 0, emitEither = 0, withinTwo = 0;
  const Image* se = o.albedoStandardError ? &*o.albedoStandardError : nullptr;
  if (se && (se->width != res || se->height != res))
    fail("eval: albedo_stderr.exr is {}x{}, the albedo {}^2", se->width, se->height, res);
  struct ObjectError {
    double abs = 0, signedSum = 0;
    size_t texels = 0;
  };  // bias vs noise, per object
  std::vector<ObjectError> objectError(ta.objectCount());
  for (size_t t = 0; t < map.texelCount(); ++t) {
    if (!map.covered(t)) continue;
    const uint32_t tri = map.triangle(t);
    const auto [uv, fitUv] = texelUvs(fm, tm, map, t);
    const int tObj = tm.faceObject[tri], fObj = fm.faceObject[tri];
    const Color truth = ta.albedoAt(tObj, uv);
    if (truthAlbedo) truthAlbedo->set(static_cast<int>(t % res), static_cast<int>(t / res), truth);
    const bool emitsTrue = ta.emissionAt(tObj, uv).maxCoeff() > 0, emitsFit = fa.emissionAt(fObj, fitUv).maxCoeff() > 0;
    emitBoth += emitsTrue && emitsFit, emitEither += emitsTrue || emitsFit;
    const int s = res / coverage.width;
    if (coverage.at(static_cast<int>(t % res) / s, static_cast<int>(t / res) / s)[0] < o.minObservations) continue;
    const Color fitted = fa.albedo.texel(static_cast<uint32_t>(t));
    const Color d = fitted - truth;
    abs += d.abs().sum() / 3, sq += d.square().sum() / 3;
    if (se) {
      const Color e = se->at(static_cast<int>(t % res), static_cast<int>(t / res));
      seSq += e.square().sum() / 3;
      for (int k = 0; k < 3; ++k) withinTwo += std::abs(d[k]) <= 2 * e[k];
    }
    for (int k = 0; k < 3; ++k) sq8 += std::pow((srgb8(fitted[k]) - srgb8(truth[k])) / 255.0, 2) / 3;
    roughSq8 += std::pow((unit8(fa.roughness[fObj]) - unit8(ta.roughness[tObj])) / 255.0, 2);
    ++c.albedoTexels;
    ObjectError& oe = objectError[tObj];
    oe.abs += d.abs().sum() / 3, oe.signedSum += d.sum() / 3, ++oe.texels;
  }
  if (c.albedoTexels) {
    c.albedoMae = abs / c.albedoTexels, c.albedoPsnr = psnrOf(sq, c.albedoTexels);
    c.albedoPsnr8 = psnrOf(sq8, c.albedoTexels), c.roughnessPsnr8 = psnrOf(roughSq8, c.albedoTexels);
    if (se)
      c.albedoStandardErrorRms = std::sqrt(seSq / c.albedoTexels),
      c.albedoWithinTwoStandardErrors = static_cast<double>(withinTwo) / (3 * c.albedoTexels);
  }
  c.emissionIou = emitEither ? static_cast<double>(emitBoth) / emitEither : 1.0;
  // Per true object. The fit's objects need not be the truth's (a computed segmentation): each
  // true object is compared with the fit's objects over its faces, weighted by area, and is found as
  // a light when the fit emits over at least half of its area. An object the fit keeps whole is
  // compared with it directly.
  struct Coverage {
    double area = 0, emitting = 0, scored = 0, roughness = 0, specular = 0;
    Eigen::Array3d emission = Eigen::Array3d::Zero();
    std::set<int> parts;  // the fit's objects over its faces
  };
  if (!o.highlightObserved.empty() && o.highlightObserved.size() != static_cast<size_t>(fa.objectCount()))
    fail("eval: materials.json lists {} objects, the fitted scene has {}", o.highlightObserved.size(),
         fa.objectCount());
  std::vector<Coverage> cover(ta.objectCount());
  std::vector<std::vector<double>> overlap(fa.objectCount(), std::vector<double>(ta.objectCount(), 0.0));
  for (size_t f = 0; f < fm.triangles.size(); ++f) {
    const int tObj = tm.faceObject[f], fObj = fm.faceObject[f];
    const double a = tm.faceArea[f];
    Coverage& cv = cover[tObj];
    cv.parts.insert(fObj);
    cv.area += a, overlap[fObj][tObj] += a;
    cv.emitting += fa.isEmissive(fObj) ? a : 0.0;
    cv.scored += o.highlightObserved.empty() || o.highlightObserved[fObj] ? a : 0.0;
    cv.roughness += a * fa.roughness[fObj], cv.specular += a * fa.specular[fObj];
    cv.emission += a * fa.meanEmission(fObj).cast<double>();
  }
  int found = 0;
  double emissionErr = 0;
  for (int obj = 0; obj < ta.objectCount(); ++obj) {
    const Coverage& cv = cover[obj];
    if (cv.area <= 0) continue;
    const int one = cv.parts.size() == 1 ? *cv.parts.begin() : -1;
    const bool materials =
        one >= 0 ? o.highlightObserved.empty() || o.highlightObserved[one] : cv.scored >= cv.area / 2;
    const bool trueEmitter = ta.isEmissive(obj);
    const bool fitEmitter = one >= 0 ? fa.isEmissive(one) : cv.emitting >= cv.area / 2;
    const float roughness = one >= 0 ? fa.roughness[one] : static_cast<float>(cv.roughness / cv.area);
    const float specular = one >= 0 ? fa.specular[one] : static_cast<float>(cv.specular / cv.area);
    const Color te = ta.meanEmission(obj);
    const Color fe = one >= 0 ? fa.meanEmission(one) : Color((cv.emission / cv.area).cast<float>());
    Json row = {{"id", obj},
                {"name", ta.names[obj]},
                {"roughness", {roughness, ta.roughness[obj]}},
                {"specular", {specular, ta.specular[obj]}},
                {"materials_scored", materials},
                {"emitter", {fitEmitter, trueEmitter}}};
    if (one < 0) row["fit_objects"] = cv.parts.size();
    if (const ObjectError& oe = objectError[obj]; oe.texels)
      row["albedo"] = {{"texels", oe.texels}, {"mae", oe.abs / oe.texels}, {"bias", oe.signedSum / oe.texels}};
    if (!trueEmitter) {
      const double roughnessError = std::abs(roughness - ta.roughness[obj]);
      const double specularError = std::abs(specular - ta.specular[obj]);
      c.roughnessMaeAll += roughnessError, c.specularMaeAll += specularError, ++c.opaqueObjects;
      if (materials) c.roughnessMae += roughnessError, c.specularMae += specularError, ++c.materialObjects;
    }
    c.emittersTrue += trueEmitter, c.emittersCorrect += trueEmitter && fitEmitter;
    if (trueEmitter && fitEmitter) {
      const double err = ((fe - te).abs() / te.max(1e-6f)).mean();
      row["emission_rel_error"] = err;
      emissionErr += err, ++found;
    }
    c.perObject.push_back(row);
  }
  // Found: the true lights found, and each of the fit's lights that lies mostly on a true reflector.
  c.emittersFound = c.emittersCorrect;
  for (int j = 0; j < fa.objectCount(); ++j) {
    if (!fa.isEmissive(j)) continue;
    const auto& row = overlap[j];
    const int mostly = static_cast<int>(std::max_element(row.begin(), row.end()) - row.begin());
    if (row[mostly] > 0 && !ta.isEmissive(mostly)) ++c.emittersFound;
  }
  if (c.materialObjects) c.roughnessMae /= c.materialObjects, c.specularMae /= c.materialObjects;
  if (c.opaqueObjects) c.roughnessMaeAll /= c.opaqueObjects, c.specularMaeAll /= c.opaqueObjects;
  c.emissionRelError = found ? emissionErr / found : 1.0;
  return c;
}

namespace {

// What a pixel's centre ray meets first: the object (-1: nothing) and its albedo there.
struct AlbedoPixel {
  int object = -1;
  Color albedo = Color::Zero();
  Vec2 uv = Vec2::Zero();
  float depth = 0;  // along the ray
};

std::vector<AlbedoPixel> albedoView(const Scene& scene, const Appearance& appearance, const Camera& camera) {
  std::vector<AlbedoPixel> view(static_cast<size_t>(camera.width) * camera.height);
  tbb::parallel_for(0, camera.height, [&](int y) {
    for (int x = 0; x < camera.width; ++x) {
      const std::optional<Vec3> dir = camera.rayDirection(Vec2(x + 0.5f, y + 0.5f));
      if (!dir) continue;
      const std::optional<SurfaceHit> hit = scene.intersect(camera.position, *dir);
      if (!hit) continue;
      AlbedoPixel& p = view[static_cast<size_t>(y) * camera.width + x];
      p.object = hit->object, p.uv = hit->uv, p.albedo = appearance.albedoAt(hit->object, hit->uv), p.depth = hit->t;
    }
  });
  return view;
}

}  // namespace

Json AlbedoViewComparison::toJson() const {
  return {{"pixels", pixels}, {"mae", mae}, {"psnr", psnr}, {"objects", perObject}};
}

// Two meshes meet a ray on the same surface when their depths differ by less than this, in metres
// and as a share of the depth (a scan's noise is millimetres; a missing object moves it by its size).
constexpr float kSameSurface = 0.02f;

AlbedoViewComparison compareAlbedoViews(const SceneDescription& fit, const SceneDescription* truth,
                                        const std::vector<Frame>& views, const Image* coverage, int minObservations,
                                        const std::filesystem::path& out) {
  const Scene fitScene(fit.mesh);
  const std::optional<Scene> truthScene = truth ? std::optional<Scene>(std::in_place, truth->mesh) : std::nullopt;
  const Appearance& objects = truth ? truth->appearance : fit.appearance;  // whose objects count and mask
  struct ObjectError {
    double abs = 0, signedSum = 0;
    size_t pixels = 0;
  };
  std::vector<ObjectError> objectError(objects.objectCount());
  double abs = 0, sq = 0;
  AlbedoViewComparison c;
  for (const Frame& frame : views) {
    const Camera& cam = frame.camera;
    const std::vector<AlbedoPixel> f = albedoView(fitScene, fit.appearance, cam);
    const std::vector<AlbedoPixel> t =
        truth ? albedoView(*truthScene, truth->appearance, cam) : std::vector<AlbedoPixel>();
    const std::vector<AlbedoPixel>& seen = truth ? t : f;
    std::optional<Image> pass;
    if (!frame.albedo.empty()) {
      pass = readImage(frame.albedo);
      if (pass->width != cam.width || pass->height != cam.height)
        fail("{}: albedo pass is {}x{}, its frame {}x{}", frame.albedo.string(), pass->width, pass->height,
             cam.width, cam.height);
    } else if (!truth) {
      fail("eval: {} has no albedo_path and no --truth gives its albedo", frame.image.string());
    }
    Image fitImage(cam.width, cam.height), referenceImage(cam.width, cam.height);
    for (int y = 1; y + 1 < cam.height; ++y)
      for (int x = 1; x + 1 < cam.width; ++x) {
        const size_t i = static_cast<size_t>(y) * cam.width + x;
        const int object = seen[i].object;
        if (object < 0 || f[i].object < 0 || objects.isEmissive(object)) continue;
        bool interior = true;
        for (int dy = -1; dy <= 1 && interior; ++dy)
          for (int dx = -1; dx <= 1; ++dx) interior &= seen[i + dy * cam.width + dx].object == object;
        if (!interior) continue;
        if (truth && std::abs(f[i].depth - t[i].depth) > std::max(kSameSurface, kSameSurface * t[i].depth))
          continue;  // the two meshes meet the ray on different surfaces: an object one of them lacks
        if (coverage) {
          const Vec2 uv = f[i].uv;
          const int cx = std::clamp(static_cast<int>(uv.x() * coverage->width), 0, coverage->width - 1);
          const int cy = std::clamp(static_cast<int>(uv.y() * coverage->height), 0, coverage->height - 1);
          if (coverage->at(cx, cy)[0] < minObservations) continue;
        }
        const Color reference = pass ? pass->at(x, y) : t[i].albedo;
        const Color d = f[i].albedo - reference;
        abs += d.abs().sum() / 3, sq += d.square().sum() / 3, ++c.pixels;
        ObjectError& oe = objectError[object];
        oe.abs += d.abs().sum() / 3, oe.signedSum += d.sum() / 3, ++oe.pixels;
        fitImage.set(x, y, f[i].albedo), referenceImage.set(x, y, reference);
      }
    if (!out.empty()) {
      const std::string stem = frame.image.stem().string();
      writePng(out / ("albedo_" + stem + ".png"), fitImage);
      writePng(out / ("albedo_reference_" + stem + ".png"), referenceImage);
    }
  }
  if (c.pixels) c.mae = abs / c.pixels, c.psnr = psnrOf(sq, c.pixels);
  for (int obj = 0; obj < objects.objectCount(); ++obj)
    if (const ObjectError& oe = objectError[obj]; oe.pixels)
      c.perObject.push_back({{"id", obj},
                             {"name", objects.names[obj]},
                             {"pixels", oe.pixels},
                             {"mae", oe.abs / oe.pixels},
                             {"bias", oe.signedSum / oe.pixels}});
  return c;
}

void runEvaluation(const EvalOptions& o) {
  const SceneDescription scene = loadSceneFile(o.scene);
  RenderOptions ro;
  ro.spp = o.spp;
  if (!o.truth.empty() && o.coverage.empty()) fail("eval: --truth needs --coverage (prepare's coverage.exr)");
  createDirectories(o.out);
  const ViewComparison v = compareViews(scene, o.cameras, ro, o.out);
  Json report = {{"views", v.toJson()}};
  const std::vector<Frame> views = readTransforms(o.cameras).frames;
  const bool passes = std::any_of(views.begin(), views.end(), [](const Frame& f) { return !f.albedo.empty(); });
  const std::optional<SceneDescription> truth =
      o.truth.empty() ? std::nullopt : std::optional<SceneDescription>(loadSceneFile(o.truth));
  const std::optional<Image> coverage = o.coverage.empty() ? std::nullopt : std::optional<Image>(readImage(o.coverage));
  const TruthOptions options = truthOptionsFor(o.scene);
  std::optional<TruthComparison> t;
  const std::string different = truth ? differentTriangles(scene.mesh, truth->mesh) : "";
  if (!different.empty())  // a scan that lacks an object: the views still compare
    spdlog::warn("eval: {}; the texel measures are skipped, the albedo in the views is scored", different);
  if (truth && different.empty()) {
    Image truthAlbedo;
    t = compareWithTruth(scene, *truth, *coverage, options, &truthAlbedo);
    report["truth"] = t->toJson();
    writeExr(o.out / "albedo_truth.exr", truthAlbedo);  // per texel of the fit's atlas: for analyses
  }
  std::optional<AlbedoViewComparison> a, ofTruth;
  if (truth || passes) {
    const SceneDescription* reference = truth ? &*truth : nullptr;
    a = compareAlbedoViews(scene, reference, views, coverage ? &*coverage : nullptr, options.minObservations, o.out);
    report["albedo_views"] = a->toJson();
    // The true albedo rendered by relume against the passes: how close a perfect fit could come.
    if (truth && passes) {
      ofTruth = compareAlbedoViews(*truth, reference, views, nullptr, options.minObservations);
      report["albedo_views_of_truth"] = ofTruth->toJson();
    }
  }
  writeJson(o.out / "eval.json", report);  // before printing: the results outlive a closed stdout
  fmt::print("views: PSNR {:.2f} dB, MSRE {:.4f} over {} frames\n", v.psnr, v.msre, v.framePsnr.size());
  if (t) {
    fmt::print(
        "albedo: MAE {:.4f}, PSNR {:.2f} dB over {} texels; roughness MAE {:.3f}, specular MAE {:.3f} over {} objects "
        "that are no light ({:.3f}, {:.3f} over the {} with observed highlights); emitters {}/{} found ({} found in "
        "all), emission error {:.2f}%\n",
        t->albedoMae, t->albedoPsnr, t->albedoTexels, t->roughnessMaeAll, t->specularMaeAll, t->opaqueObjects,
        t->roughnessMae, t->specularMae, t->materialObjects, t->emittersCorrect, t->emittersTrue, t->emittersFound,
        100 * t->emissionRelError);
    fmt::print(
        "peers' measures: albedo PSNR {:.2f} dB (8-bit sRGB maps), roughness PSNR {:.2f} dB (8-bit maps), emission IoU "
        "{:.3f}\n",
        t->albedoPsnr8, t->roughnessPsnr8, t->emissionIou);
    if (t->albedoStandardErrorRms >= 0)
      fmt::print("albedo standard errors: RMS {:.4f} against an error RMS of {:.4f}; {:.1f}% of errors within two\n",
                 t->albedoStandardErrorRms, t->albedoErrorRms(), 100 * t->albedoWithinTwoStandardErrors);
    for (const Json& object : t->perObject) fmt::print("  {}\n", object.dump());
  }
  if (a)
    fmt::print("albedo in the views{}: MAE {:.4f}, PSNR {:.2f} dB over {} pixels (objects' interiors, lights out)\n",
               passes ? " against their albedo passes" : "", a->mae, a->psnr, a->pixels);
  if (ofTruth)
    fmt::print("  the true albedo against the same passes: MAE {:.4f}, PSNR {:.2f} dB over {} pixels\n", ofTruth->mae,
               ofTruth->psnr, ofTruth->pixels);
}

}  // namespace relume
