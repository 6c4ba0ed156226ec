#include "scenes/demo.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "capture/frame_image.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "product/evaluate.h"
#include "product/prepare.h"
#include "render/lights.h"

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

SynthCaptureOptions DemoOptions::captureOptions(const fs::path& capture) {
  SynthCaptureOptions so;
  so.out = capture;
  so.testWidth = 128, so.testHeight = 96;
  so.testSpp = 32;
  return so;
}

namespace {

// The held-out views re-rendered from the fit and from the truth with the same random numbers:
// each against the references (the truth's score is the floor the references' and the
// re-renders' noise sets), and the fit against the truth, where their common noise cancels.
struct HeldOut {
  ViewComparison fit, truth;    // against the references
  ViewComparison fitVsTruth;    // the reconstruction's error
  ViewComparison noiseVsTruth;  // the truth plus the noise left in fit - truth: what that noise alone scores
  double beyondNoisePsnr = 0;   // fitVsTruth with that noise's squared error taken out, mean over frames
  Json views = Json::array();   // frame names
  double seconds = 0;
  Json toJson() const {
    return {{"views", views},
            {"fit", fit.toJson()},
            {"truth", truth.toJson()},
            {"fit_vs_truth", fitVsTruth.toJson()},
            {"noise_vs_truth", noiseVsTruth.toJson()},
            {"fit_vs_truth_beyond_noise_psnr", beyondNoisePsnr}};
  }
};

void addScore(ViewComparison& v, const ImageScore& s) {
  v.framePsnr.push_back(s.psnr), v.frameMsre.push_back(s.msre);
  const double n = static_cast<double>(v.framePsnr.size());
  v.psnr += (s.psnr - v.psnr) / n, v.msre += (s.msre - v.msre) / n;  // running means
}

// A PSNR with the squared error of an independent noise that alone scores `noisePsnr` taken out.
double psnrWithout(double psnr, double noisePsnr) {
  const double mse = std::pow(10.0, -psnr / 10), noiseMse = std::pow(10.0, -noisePsnr / 10);
  return -10.0 * std::log10(std::max(mse - noiseMse, 1e-12));
}

// Writes OUT/reference_views, OUT/test_views (the fit's re-renders) and OUT/error_views
// (|fit - truth| x 4 per 2x2 pixels, which halves the noise left in it), PNG at exposure 1 (and the
// re-renders as EXR).
HeldOut scoreHeldOut(const SceneDescription& fitted, const SceneDescription& truth, const fs::path& cameras, int spp,
                     const fs::path& out) {
  Timer timer;
  const Capture cap = readTransforms(cameras);
  const Scene fitScene(fitted.mesh), truthScene(truth.mesh);
  const LightSampler fitLights(fitScene, fitted.appearance), truthLights(truthScene, truth.appearance);
  for (const char* dir : {"reference_views", "test_views", "error_views"}) createDirectories(out / dir);
  HeldOut h;
  Progress progress("held-out views", cap.frames.size());
  for (size_t i = 0; i < cap.frames.size(); ++i) {
    const Frame& frame = cap.frames[i];
    const std::string stem = frame.image.stem().string(), name = frame.image.string();
    RenderOptions ro;  // at the capture's depth (kDefaultMaxDepth): a shallower re-render is darker
    ro.spp = spp, ro.seed = i;
    const Image reference = loadFrameImage(frame);
    const SplitRender fit = renderSplit(fitScene, fitted.appearance, fitLights, frame.camera, ro);
    const SplitRender tru = renderSplit(truthScene, truth.appearance, truthLights, frame.camera, ro);
    addScore(h.fit, scoreImage(fit.mean, reference, name));
    addScore(h.truth, scoreImage(tru.mean, reference, name));
    addScore(h.fitVsTruth, scoreImage(fit.mean, tru.mean, name));
    Image noisy = tru.mean;
    for (size_t k = 0; k < noisy.rgb.size(); ++k) noisy.rgb[k] += fit.noise.rgb[k] - tru.noise.rgb[k];
    addScore(h.noiseVsTruth, scoreImage(noisy, tru.mean, name));
    h.beyondNoisePsnr += psnrWithout(h.fitVsTruth.framePsnr.back(), h.noiseVsTruth.framePsnr.back()) /
                         static_cast<double>(cap.frames.size());
    const ViewError e = errorAgainstTruth(fit, tru, reference, 2);
    writePng(out / "reference_views" / (stem + ".png"), reference);
    writeExr(out / "test_views" / (stem + ".exr"), fit.mean);
    writePng(out / "test_views" / (stem + ".png"), fit.mean);
    writePng(out / "error_views" / (stem + ".png"), e.error, 4.0f);
    h.views.push_back(stem);
    progress.advance();
  }
  h.seconds = timer.seconds();
  return h;
}

void writeReport(const fs::path& out, const Json& s) {
  const Json& t = s["truth"];
  std::string md = "# relume demo: reconstruction of the synthetic room\n\n";
  md += fmt::format(
      "Synthetic room, {} training frames; synth {:.0f} s, prepare {:.0f} s, fit {:.0f} s ({} iterations), "
      "fit report {:.0f} s, held-out views {:.0f} s; {:.0f} s in all, peak RSS {:.0f} MiB.\n\n",
      s["frames"].get<int>(), s["synth_seconds"].get<double>(), s["prepare_seconds"].get<double>(),
      s["fit_seconds"].get<double>(), s["fit_iterations"].get<int>(), s["report_seconds"].get<double>(),
      s["test_seconds"].get<double>(), s["seconds"].get<double>(), s["peak_rss_mb"].get<double>());
  md += "| measure | value |\n| --- | --- |\n";
  md += fmt::format("| albedo MAE (texels observed >= 5 times) | {:.4f} |\n", s["albedo_mae"].get<double>());
  md += fmt::format("| albedo PSNR | {:.2f} dB |\n", s["albedo_psnr"].get<double>());
  md += fmt::format("| roughness MAE / specular MAE ({} objects that are no light) | {:.3f} / {:.3f} |\n",
                    t["opaque_objects"].get<int>(), s["roughness_mae_all"].get<double>(),
                    s["specular_mae_all"].get<double>());
  md +=
      fmt::format("| roughness MAE / specular MAE ({} objects with observed highlights) | {:.3f} / {:.3f} |\n",
                  t["material_objects"].get<int>(), s["roughness_mae"].get<double>(), s["specular_mae"].get<double>());
  md += fmt::format("| emitters true / found / correct | {} / {} / {} |\n", s["emitters_true"].get<int>(),
                    s["emitters_found"].get<int>(), t["emitters_correct"].get<int>());
  md += fmt::format("| emission relative error | {:.2f}% |\n", 100 * s["emission_rel_error"].get<double>());
  md += fmt::format("| held-out test views: PSNR / MSRE against the references | {:.2f} dB / {:.4f} |\n",
                    s["test_psnr"].get<double>(), s["test_msre"].get<double>());
  md += fmt::format("| the truth re-rendered the same way (the noise floor) | {:.2f} dB / {:.4f} |\n",
                    s["test_noise_floor_psnr"].get<double>(), s["test_noise_floor_msre"].get<double>());
  md += fmt::format(
      "| held-out views against the truth rendered with the same random numbers | {:.2f} dB (the noise left alone: "
      "{:.2f} dB; without it: {:.1f} dB) |\n\n",
      s["test_truth_psnr"].get<double>(), s["test_truth_noise_psnr"].get<double>(),
      s["test_truth_beyond_noise_psnr"].get<double>());
  const auto size = s["test_size"];
  md += fmt::format(
      "The {} held-out views ({}x{}) have references rendered from the truth at {} spp, as a photo would be taken, and "
      "are "
      "re-rendered from the fit and from the truth at {} spp with the same random numbers. Against the references, "
      "noise "
      "is part of every score: the truth itself scores {:.2f} dB, the ceiling for the fit's {:.2f} dB. Against the "
      "truth "
      "re-rendered with the same random numbers the two scenes' common noise cancels, so {:.2f} dB is mostly the "
      "reconstruction's own error; the noise left in that difference (paths the two scenes scatter differently), "
      "measured "
      "from each re-render's two independent halves, would alone score {:.2f} dB, and without it the fit scores about "
      "{:.1f} dB. The error pictures average |fit - truth| over 2x2 pixels, which halves that noise.\n\n",
      s["test_views"].size(), size[0].get<int>(), size[1].get<int>(), s["test_reference_spp"].get<int>(),
      s["test_spp"].get<int>(), s["test_noise_floor_psnr"].get<double>(), s["test_psnr"].get<double>(),
      s["test_truth_psnr"].get<double>(), s["test_truth_noise_psnr"].get<double>(),
      s["test_truth_beyond_noise_psnr"].get<double>());
  md += "## Albedo: median init, reconstruction, ground truth\n\n";
  md += "![init](work/albedo_init.png) ![fit](work/result/albedo.png) ![truth](albedo_truth.png)\n\n";
  md += "## Held-out views: reference, re-rendered reconstruction, |fit - truth| x 4 (same random numbers)\n\n";
  for (const char* row : {"reference_views", "test_views", "error_views"}) {
    for (const auto& name : s["test_views"]) md += fmt::format("![{}]({}/{}.png) ", row, row, name.get<std::string>());
    md += "\n\n";
  }
  md +=
      "## Per object (fit, truth)\n\n| id | name | roughness | specular | emitter | scored |\n| --- | --- | --- | --- "
      "| --- | --- |\n";
  for (const Json& o : t["objects"])
    md += fmt::format("| {} | {} | {:.3f}, {:.3f} | {:.3f}, {:.3f} | {}, {} | {} |\n", o["id"].get<int>(),
                      o["name"].get<std::string>(), o["roughness"][0].get<double>(), o["roughness"][1].get<double>(),
                      o["specular"][0].get<double>(), o["specular"][1].get<double>(), o["emitter"][0].get<bool>(),
                      o["emitter"][1].get<bool>(),
                      o["materials_scored"].get<bool>() ? "yes" : "no (no highlight observed)");
  md +=
      "\nFiles: `work/result/` (scene.json, albedo.exr/.png, materials.json), `work/metrics.jsonl` (loss and "
      "timings per 10 iterations), `summary.json`. The fit's own report, with loss curves and timings: "
      "[work/report/index.html](work/report/index.html).\n";
  writeTextAtomically(out / "report.md", md);
}

}  // namespace

DemoCapture prepareDemoCapture(const fs::path& out) {
  DemoCapture d{out / "capture", out / "work"};
  const SynthCaptureOptions so = DemoOptions::captureOptions(d.capture);
  Timer ts;
  if (!pathExists(so.out / "transforms_test.json")) writeSynthCapture(so);  // written last
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
  // CPU seconds of each phase, all threads: a cost that other processes sharing the cores do not inflate.
  Json cpu = Json::object();
  double mark = processCpuSeconds();
  auto lap = [&](const char* phase) {
    const double now = processCpuSeconds();
    cpu[phase] = now - mark;
    mark = now;
  };
  const DemoCapture d = prepareDemoCapture(o.out);
  lap("synth_and_prepare");
  const FitSummary fs = runFit(d.work, o.fit, false);
  lap("fit");
  Timer reportTimer;
  writeFitReport(d.work, o.report);
  const double reportSeconds = reportTimer.seconds();
  lap("report");

  const SceneDescription fitted = loadSceneFile(fs.resultDir / "scene.json");
  const SceneDescription truth = loadSceneFile(d.capture / "gt" / "scene.json");
  const TruthOptions to = truthOptionsFor(fs.resultDir / "scene.json");
  Image truthAlbedo;
  const TruthComparison tc = compareWithTruth(fitted, truth, readImage(d.work / "coverage.exr"), to, &truthAlbedo);
  writePng(o.out / "albedo_truth.png", truthAlbedo);
  const HeldOut h = scoreHeldOut(fitted, truth, d.capture / "transforms_test.json", o.testSpp, o.out);
  lap("truth_and_test");
  const SynthCaptureOptions so = DemoOptions::captureOptions(d.capture);
  Json s = {{"fit_seconds", fs.seconds},
            {"fit_iterations", fs.iterations},
            {"synth_seconds", d.synthSeconds},
            {"prepare_seconds", d.prepareSeconds},
            {"report_seconds", reportSeconds},
            {"test_seconds", h.seconds},
            {"frames", static_cast<int>(d.frames)},
            {"albedo_mae", tc.albedoMae},
            {"albedo_psnr", tc.albedoPsnr},
            {"roughness_mae", tc.roughnessMae},
            {"specular_mae", tc.specularMae},
            {"roughness_mae_all", tc.roughnessMaeAll},
            {"specular_mae_all", tc.specularMaeAll},
            {"emitters_true", tc.emittersTrue},
            {"emitters_found", tc.emittersFound},
            {"emission_rel_error", tc.emissionRelError},
            {"test_psnr", h.fit.psnr},
            {"test_msre", h.fit.msre},
            {"test_noise_floor_psnr", h.truth.psnr},
            {"test_noise_floor_msre", h.truth.msre},
            {"test_truth_psnr", h.fitVsTruth.psnr},
            {"test_truth_noise_psnr", h.noiseVsTruth.psnr},
            {"test_truth_beyond_noise_psnr", h.beyondNoisePsnr},
            {"test_reference_spp", so.testSpp},
            {"test_spp", o.testSpp},
            {"test_size", {so.testWidth, so.testHeight}},
            {"peak_rss_mb", peakRssMiB()},
            {"seconds", total.seconds()},
            {"cpu_seconds", cpu},
            {"truth", tc.toJson()},
            {"test", h.fit.toJson()},
            {"held_out", h.toJson()},
            {"test_views", h.views},
            {"fit_config", o.fit.toJson()}};
  writeJson(o.out / "summary.json", s);
  writeReport(o.out, s);
  return s;
}

}  // namespace relume
