#include "product/fit_result.h"

#include <spdlog/spdlog.h>

#include "core/check.h"
#include "core/kill_point.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "product/confidence.h"

namespace relume {
namespace fs = std::filesystem;

fs::path writeFitResult(const Workspace& w, const Appearance& appearance, const TexelSpace& space,
                        const ObjectRoles& roles, const FitConfig& c, const Json& frames,
                        const FitProgress& progress, const SettledAlbedo& settled) {
  const fs::path result = w.dir / "result", staging = w.dir / "result.partial";
  removeAll(staging);
  createDirectories(staging);
  SceneDescription desc{w.dir / "atlas_mesh.ply", w.mesh, appearance};
  saveSceneFile(staging / "scene.json", desc);
  Image albedo(space.resolution, space.resolution);
  albedo.rgb = appearance.albedo.rgb;
  writePng(staging / "albedo.png", albedo);
  if (!settled.standardError.empty()) {
    CHECK(settled.standardError.size() == albedo.rgb.size());
    Image error(space.resolution, space.resolution);
    for (size_t t = 0; t < space.map.texelCount(); ++t)
      for (size_t c = 3 * t; c < 3 * t + 3; ++c)
        error.rgb[c] = space.map.covered(t) ? settled.error(c) : 0.0f;
    writeExr(staging / "albedo_stderr.exr", error);
    writePng(staging / "albedo_stderr.png", error, 10.0f);
  }
  const fs::path agreementFile = w.dir / "agreement.exr";
  const TexelConfidence confidence =
      texelConfidence(w, space, appearance, roles,
                      pathExists(agreementFile) ? std::optional<Image>(readImage(agreementFile)) : std::nullopt,
                      settled, settled.beyondOneKnown ? std::optional<Image>(w.medianRadiance()) : std::nullopt);
  writeExr(staging / "confidence.exr", confidence.channels);
  writePng(staging / "confidence.png", confidencePicture(confidence, space.resolution));
  writeJson(staging / "confidence.json", confidence.summary);
  if (const Json u = confidence.summary.value("unplaced_light", Json());
      u.is_object() && u.at("share_of_observed").get<double>() >= kUnplacedLightNotice) {
    const Json& top = u.at("objects").front();
    spdlog::warn(
        "fit: at least {:.1f}% of the radiance the frames show on reflectors is more than albedo 1 returns under the "
        "fitted lights, most on object {} ({}): a light no frame shows lights them (result/confidence.json)",
        100 * u.at("share_of_observed").get<double>(), top.at("id").get<int>(), top.at("name").get<std::string>());
  }
  Json materials = Json::array();
  std::vector<size_t> observed(appearance.objectCount(), 0), total(appearance.objectCount(), 0);
  for (size_t t = 0; t < space.map.texelCount(); ++t)
    if (space.map.covered(t)) {
      const int o = space.objectOf(t, w.mesh);
      ++total[o];
      observed[o] += space.updatable[t];
    }
  for (int o = 0; o < appearance.objectCount(); ++o) {
    const Color e = appearance.meanEmission(o);
    materials.push_back({{"id", o},
                         {"name", appearance.names[o]},
                         {"roughness", appearance.roughness[o]},
                         {"specular", appearance.specular[o]},
                         {"emission", {e[0], e[1], e[2]}},
                         {"is_emitter", appearance.isEmissive(o)},
                         {"out_of_model", roles.outOfModel[o] != 0},
                         {"highlight_observed", roles.highlight[o] != 0},
                         {"highlight_texels", roles.highlightPairs[o]},
                         {"highlight_contrast", roles.highlightContrast[o]},
                         {"roughness_at_least",
                          roles.roughnessAtLeast[o] >= 0 ? Json(roles.roughnessAtLeast[o]) : Json(nullptr)},
                         {"or_sharper_than", roles.sharpBelow[o] >= 0 ? Json(roles.sharpBelow[o]) : Json(nullptr)},
                         {"observed_texel_fraction", total[o] ? double(observed[o]) / total[o] : 0.0}});
  }
  Json summary = {
      {"objects", materials},         {"albedo_resolution", space.resolution}, {"iterations", progress.iterations},
      {"final_loss", progress.loss},  {"sampler", progress.sampler.toJson()},  {"config", c.toJson()},
      {"peak_rss_mib", peakRssMiB()}, {"memory_bytes", progress.peakMemory}};
  if (!progress.budget.is_null()) summary["time_budget"] = progress.budget;
  if (!progress.memoryBudget.is_null()) summary["memory_budget"] = progress.memoryBudget;
  if (!progress.convergence.is_null()) summary["convergence"] = progress.convergence;
  killPoint("result-half");
  writeJson(staging / "materials.json", summary);
  writeJson(staging / "lights.json",
            {{"light_test", enumName(c.lightTest)}, {"hint", c.lights}, {"decisions", roles.lightDecisions}});
  writeJson(staging / "frames.json", frames);
  removeAll(result);
  killPoint("result-staged");
  renamePath(staging, result);
  spdlog::info("fit: result in {}", result.string());
  return result;
}

double meshBytes(const TriangleMesh& m) {
  return static_cast<double>((m.positions.size() + m.normals.size()) * sizeof(Vec3) + m.uvs.size() * sizeof(Vec2) +
                             m.triangles.size() * (sizeof(Eigen::Vector3i) + sizeof(int32_t)));
}

double batchBytesPerRay() {
  return static_cast<double>(sizeof(BatchRay) + 2 * sizeof(uint32_t) + sizeof(int) + 4 * sizeof(Color));
}

double pathRecordBytes(int maxDepth) { return double(threadCount()) * adjointRecordBytesPerThread(maxDepth); }

Json fitMemory(const Workspace& w, Appearance& appearance, const TexelSpace& space, Gradients& grads,
               const Batch& batch, const AdjointSettings& settings, const GroupOptimiser& optimiser,
               const LightSampler* lights) {
  auto floats = [](size_t n) { return static_cast<double>(n * sizeof(float)); };
  double parameters = 0, gradients = floats(grads.albedoCurvature.size()) + grads.bookkeepingBytes();
  for (ParamGroup& g : paramGroups(appearance, &grads))
    parameters += floats(g.values.size()), gradients += floats(g.grads.size());
  const double texels = space.map.bytes() + space.sampleable.size() * sizeof(uint32_t) + space.updatable.size();
  const double mesh = meshBytes(w.mesh);
  const double batchBytes = static_cast<double>(batch.rays.size()) * batchBytesPerRay();
  const double records = pathRecordBytes(settings.path.maxDepth);
  Json j = {{"parameters", parameters},
            {"gradients", gradients},
            {"optimiser_state", optimiser.stateBytes()},
            {"averages", optimiser.averageBytes()},
            {"texel_map", texels},
            {"mesh", mesh},
            {"scene", static_cast<double>(w.scene->bytes())},
            {"visibility_index", static_cast<double>(w.vis.bytes())},
            {"frame_cache_mapped", static_cast<double>(w.store->mappedBytes())},
            {"batch", batchBytes},
            {"path_records", records},
            {"gradient_logs", static_cast<double>(grads.logBytes())},
            {"light_sampler", lights ? static_cast<double>(lights->bytes()) : 0.0}};
  double total = 0;
  for (const auto& [k, v] : j.items())
    if (k != "frame_cache_mapped") total += v.get<double>();
  j["total"] = total;  // without the frame cache, which is file-backed and mostly not resident
  return j;
}

}  // namespace relume
