#include "scenes/demo.h"

#include <spdlog/spdlog.h>

#include "core/system.h"
#include "io/atomic_file.h"
#include "io/image.h"
#include "product/evaluate.h"
#include "product/prepare.h"
#include "scenes/synth.h"

namespace relume {
namespace fs = std::filesystem;

FitConfig DemoOptions::demoFitConfig() {
  FitConfig c;
  c.batchTexels = 8192;
  c.emissionIterations = 100;
  c.materialIterations = 150;
  c.albedoPasses = 40;
  c.samplesPerRay = 1;  // the fit's default 2 costs ~1.8x per iteration: the demo keeps to its 5 minutes
  c.emissionTextureIterations = 40;
  return c;
}

namespace {

void writeReport(const fs::path& out, const Json& s) {
  const Json& t = s["truth"];
  std::string md = "# relume demo: reconstruction of the synthetic room\n\n";
  md += fmt::format("Synthetic room, {} training frames; synth {:.0f} s, prepare {:.0f} s, fit {:.0f} s ({} iterations), "
                    "peak RSS {:.0f} MiB.\n\n",
                    s["frames"].get<int>(), s["synth_seconds"].get<double>(), s["prepare_seconds"].get<double>(),
                    s["fit_seconds"].get<double>(), s["fit_iterations"].get<int>(), s["peak_rss_mb"].get<double>());
  md += "| measure | value |\n| --- | --- |\n";
  md += fmt::format("| albedo MAE (texels observed >= 5 times) | {:.4f} |\n", s["albedo_mae"].get<double>());
  md += fmt::format("| albedo PSNR | {:.2f} dB |\n", s["albedo_psnr"].get<double>());
  md += fmt::format("| roughness MAE / specular MAE ({} objects with observed highlights) | {:.3f} / {:.3f} |\n",
                    t["material_objects"].get<int>(), s["roughness_mae"].get<double>(), s["specular_mae"].get<double>());
  md += fmt::format("| emitters true / found / correct | {} / {} / {} |\n", s["emitters_true"].get<int>(),
                    s["emitters_found"].get<int>(), t["emitters_correct"].get<int>());
  md += fmt::format("| emission relative error | {:.2f}% |\n", 100 * s["emission_rel_error"].get<double>());
  md += fmt::format("| held-out test views: PSNR / MSRE | {:.2f} dB / {:.4f} |\n\n", s["test_psnr"].get<double>(),
                    s["test_msre"].get<double>());
  md += "## Albedo: median init, reconstruction, ground truth\n\n";
  md += "![init](work/albedo_init.png) ![fit](work/result/albedo.png) ![truth](albedo_truth.png)\n\n";
  md += "## Held-out views: reference (top) and re-rendered reconstruction (bottom)\n\n";
  for (const auto& name : s["test_views"]) md += fmt::format("![ref](reference_views/{}.png) ", name.get<std::string>());
  md += "\n\n";
  for (const auto& name : s["test_views"]) md += fmt::format("![fit](test_views/{}.png) ", name.get<std::string>());
  md += "\n\n## Per object (fit, truth)\n\n| id | name | roughness | specular | emitter | scored |\n| --- | --- | --- | --- | --- | --- |\n";
  for (const Json& o : t["objects"])
    md += fmt::format("| {} | {} | {:.3f}, {:.3f} | {:.3f}, {:.3f} | {}, {} | {} |\n", o["id"].get<int>(), o["name"].get<std::string>(),
                      o["roughness"][0].get<double>(), o["roughness"][1].get<double>(), o["specular"][0].get<double>(),
                      o["specular"][1].get<double>(), o["emitter"][0].get<bool>(), o["emitter"][1].get<bool>(),
                      o["materials_scored"].get<bool>() ? "yes" : "no (no highlight observed)");
  md += "\nFiles: `work/result/` (scene.json, albedo.exr/.png, materials.json), `work/metrics.jsonl` (loss and "
        "timings per 10 iterations), `summary.json`. The fit's own report, with loss curves and timings: "
        "[work/report/index.html](work/report/index.html).\n";
  writeTextAtomically(out / "report.md", md);
}

}  // namespace

DemoCapture prepareDemoCapture(const fs::path& out) {
  DemoCapture d{out / "capture", out / "work"};
  SynthCaptureOptions so;
  so.out = d.capture;
  Timer ts;
  if (!fs::exists(so.out / "transforms_test.json")) writeSynthCapture(so);  // written last
  d.synthSeconds = ts.seconds();
  PrepareOptions po;
  po.resolutions = {512, 1024};  // the demo's 256x192 frames resolve about 512^2 of this atlas
  po.atlas.gutterResolution = 512;
  const PrepareSummary ps = prepareCapture(so.out, d.work, po);
  d.prepareSeconds = ps.seconds;
  d.frames = ps.frames;
  return d;
}

Json runDemo(const DemoOptions& o) {
  Timer total;
  const DemoCapture d = prepareDemoCapture(o.out);
  SynthCaptureOptions so;
  so.out = d.capture;
  const FitSummary fs = runFit(d.work, o.fit, false);

  const SceneDescription fitted = loadSceneFile(fs.resultDir / "scene.json");
  const SceneDescription truth = loadSceneFile(so.out / "gt" / "scene.json");
  const TruthOptions to = truthOptionsFor(fs.resultDir / "scene.json");
  Image truthAlbedo;
  const TruthComparison tc = compareWithTruth(fitted, truth, readImage(o.out / "work" / "coverage.exr"), to, &truthAlbedo);
  writePng(o.out / "albedo_truth.png", truthAlbedo);

  RenderOptions ro;
  ro.spp = o.testSpp;  // at the capture's depth (kDefaultMaxDepth): a shallower re-render is darker
  fs::create_directories(o.out / "test_views");
  const ViewComparison vc = compareViews(fitted, so.out / "transforms_test.json", ro, o.out / "test_views");
  // References as PNG beside them, for the report.
  Json views = Json::array();
  fs::create_directories(o.out / "reference_views");
  for (const Frame& f : readTransforms(so.out / "transforms_test.json").frames) {
    views.push_back(f.image.stem().string());
    writePng(o.out / "reference_views" / (f.image.stem().string() + ".png"), loadFrameImage(f));
  }
  Json s = {{"fit_seconds", fs.seconds}, {"fit_iterations", fs.iterations}, {"synth_seconds", d.synthSeconds},
            {"prepare_seconds", d.prepareSeconds}, {"frames", static_cast<int>(d.frames)},
            {"albedo_mae", tc.albedoMae}, {"albedo_psnr", tc.albedoPsnr}, {"roughness_mae", tc.roughnessMae},
            {"specular_mae", tc.specularMae}, {"emitters_true", tc.emittersTrue}, {"emitters_found", tc.emittersFound},
            {"emission_rel_error", tc.emissionRelError}, {"test_psnr", vc.psnr}, {"test_msre", vc.msre},
            {"peak_rss_mb", peakRssMiB()}, {"seconds", total.seconds()}, {"truth", tc.toJson()},
            {"test", vc.toJson()}, {"test_views", views}, {"fit_config", o.fit.toJson()}};
  writeJson(o.out / "summary.json", s);
  writeReport(o.out, s);
  return s;
}

}  // namespace relume
