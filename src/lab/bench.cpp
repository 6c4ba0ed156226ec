#include "lab/bench.h"

#include <spdlog/spdlog.h>

#include <fstream>
#include <map>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "core/system.h"
#include "scenes/demo.h"
#include "product/evaluate.h"
#include "product/prepare.h"
#include "product/report.h"

namespace relume {
namespace fs = std::filesystem;

const std::vector<BenchSweep>& benchSweeps() {
  static const std::vector<BenchSweep> sweeps = {
      {"spp", "samples_per_ray", {1, 2, 4}},
      {"batch", "batch_texels", {2048, 8192, 32768}},
      {"frames_per_texel", "frames_per_texel", {1, 4, 8}},
      {"depth", "max_depth", {2, 4, 9}},
      // The Gauss-Newton albedo step is first-vertex only: both modes with the paper's Adam.
      {"gradients", "gradients", {"direct", "full"}, {{"albedo_step", "adam"}}},
      {"pairing", "pairing", {"decorrelated", "crossfit", "reuse"}},
      {"resolution", "max_resolution", {512, 1024}},
      {"sampler", "sampler", {"texture", "image"}},
      {"smoothing", "albedo_smoothing", {"none", "albedo", "guide_edges"}},
      // Seconds (wall clock), the budgets of issue 40's time-to-accuracy measure.
      {"budget", "time_budget", {60, 120, 300, 600, 1200}, Json::object(), true},
  };
  return sweeps;
}

FitConfig BenchOptions::baseConfig() {
  FitConfig c = DemoOptions::demoFitConfig();
  c.emissionIterations = 80;
  c.materialIterations = 60;
  c.albedoPasses = 10;
  c.emissionTextureIterations = 0;  // emission textures leave the albedo error alone
  c.maxResolution = 512;            // what the room's frames resolve (the resolution sweep goes beyond)
  return c;
}

namespace {

std::string valueText(const Json& v) { return v.is_string() ? v.get<std::string>() : v.dump(); }

// The error at cost t of a curve that is held constant after its last point.
double errorAt(const BenchRun& r, double t) {
  const std::vector<double>& x = r.curveCpuSeconds;
  if (x.empty()) return NAN;
  if (t >= x.back()) return r.curveMae.back();
  if (x.size() == 1) return NAN;  // a run measured only at its end
  for (size_t i = 1; i < x.size(); ++i)
    if (t <= x[i]) {
      const double f = (t - x[i - 1]) / std::max(1e-9, x[i] - x[i - 1]);
      return r.curveMae[i - 1] + std::clamp(f, 0.0, 1.0) * (r.curveMae[i] - r.curveMae[i - 1]);
    }
  return r.curveMae.front();
}

struct Evaluation {
  fs::path work;
  std::optional<SceneDescription> truth;
  Image coverage;
  fs::path testCameras;
  int testSpp = 16;

  double albedoMae(const Appearance& a, const TriangleMesh& mesh) const {
    if (!truth) return NAN;
    const TruthComparison tc =
        compareWithTruth(SceneDescription{work / "atlas_mesh.ply", mesh, a}, *truth, coverage, {});
    return tc.albedoTexels > 0 ? tc.albedoMae : NAN;  // no texel observed often enough to score
  }
};

// `evaluateEvery` 0: the albedo error is measured at the end only.
BenchRun benchRun(const fs::path& work, const FitConfig& config, const Evaluation& ev, int evaluateEvery) {
  BenchRun run;
  FitHooks hooks;
  hooks.writeFiles = false;
  const double cpuStart = processCpuSeconds();
  double cpuInHooks = 0;
  hooks.afterIteration = [&](const FitIteration& it) {
    if (evaluateEvery > 0 && (it.iteration == 1 || it.iteration % evaluateEvery == 0)) {
      const double cpu = processCpuSeconds();
      run.curveCpuSeconds.push_back(cpu - cpuStart - cpuInHooks);
      run.curveMae.push_back(ev.albedoMae(it.appearance, it.mesh));
      cpuInHooks += processCpuSeconds() - cpu;
    }
    return true;
  };
  std::optional<SceneDescription> fitted;
  hooks.finished = [&](const Appearance& a, const TriangleMesh& mesh) {
    fitted = SceneDescription{work / "atlas_mesh.ply", mesh, a};
  };
  const FitSummary s = runFit(work, config, false, hooks);
  run.seconds = s.seconds;
  run.cpuSeconds = processCpuSeconds() - cpuStart - cpuInHooks;
  run.iterations = s.iterations;
  run.memoryMiB = s.memory.value("total", 0.0) / 1048576.0;
  if (!fitted) fail("bench: the fit ended without a result");
  run.albedoMae = ev.albedoMae(fitted->appearance, fitted->mesh);
  run.curveCpuSeconds.push_back(run.cpuSeconds);
  run.curveMae.push_back(run.albedoMae);
  if (!ev.testCameras.empty()) {
    RenderOptions ro;
    ro.spp = ev.testSpp;
    ro.path.maxDepth = kDefaultMaxDepth;
    const ViewComparison vc = compareViews(*fitted, ev.testCameras, ro);
    run.psnr = vc.psnr, run.msre = vc.msre;
  }
  return run;
}

// One run's row of bench.md; `atBaselineCost`: with its error at the baseline's cost.
std::string tableRow(const std::string& value, const BenchRun& r, bool atBaselineCost) {
  return fmt::format("| {} | {:.0f} s ({:.0f} s) | {} | {:.4f} | {}{:.2f} dB | {:.4f} | {:.0f} MiB |\n", value,
                     r.seconds, r.cpuSeconds, r.iterations, r.albedoMae,
                     atBaselineCost ? fmt::format("{:.4f} | ", r.maeAtBaselineCost) : std::string(), r.psnr, r.msre,
                     r.memoryMiB);
}

// A sweep's runs by the wall clock each took: its albedo error and held-out PSNR at the end.
void writeEndCharts(const fs::path& out, const BenchSweep& sw, const std::vector<BenchRun>& runs, std::string& md) {
  ChartSeries mae, psnr;
  for (const BenchRun& r : runs)
    if (r.sweep == sw.name) {
      mae.x.push_back(r.seconds), mae.y.push_back(r.albedoMae);
      psnr.x.push_back(r.seconds), psnr.y.push_back(r.psnr);
    }
  md += fmt::format("\n![{0}: albedo MAE]({0}_mae.svg) ![{0}: held-out PSNR]({0}_psnr.svg)\n\n", sw.name);
  writeTextAtomically(out / (sw.name + "_mae.svg"),
                      lineChartSvg("albedo MAE at the end: " + sw.name, "wall seconds the fit took; MAE on a log scale",
                                   {mae}, true));
  writeTextAtomically(out / (sw.name + "_psnr.svg"), lineChartSvg("held-out PSNR at the end: " + sw.name,
                                                                  "wall seconds the fit took; dB", {psnr}, false));
}

void writeOutputs(const fs::path& out, const std::vector<BenchRun>& runs, const std::vector<const BenchSweep*>& sweeps,
                  const FitConfig& base) {
  std::string csv =
      "sweep,value,seconds,cpu_seconds,iterations,fit_memory_mib,albedo_mae,albedo_mae_at_baseline_cpu,test_psnr,test_"
      "msre\n";
  std::string curves = "sweep,value,cpu_seconds,albedo_mae\n";
  for (const BenchRun& r : runs) {
    csv += fmt::format("{},{},{:.2f},{:.2f},{},{:.1f},{:.5f},{:.5f},{:.3f},{:.5f}\n", r.sweep, r.value, r.seconds,
                       r.cpuSeconds, r.iterations, r.memoryMiB, r.albedoMae, r.maeAtBaselineCost, r.psnr, r.msre);
    for (size_t i = 0; i < r.curveCpuSeconds.size(); ++i)
      curves += fmt::format("{},{},{:.3f},{:.5f}\n", r.sweep, r.value, r.curveCpuSeconds[i], r.curveMae[i]);
  }
  writeTextAtomically(out / "bench.csv", csv);
  writeTextAtomically(out / "curves.csv", curves);
  const Json baseJson = base.toJson();
  // Sweeps from the fit's schedule alone need no baseline (runBench).
  const BenchRun* baseline = runs.front().sweep == "baseline" ? &runs.front() : nullptr;
  std::string md;
  if (baseline)
    md = fmt::format(
        "Baseline: {:.0f} s ({:.0f} CPU s), {} iterations, albedo MAE {:.4f}, held-out PSNR {:.2f} dB / MSRE {:.4f}. "
        "Each row changes one setting; \"MAE at {:.0f} CPU s\" is its albedo error when it had used as much CPU as "
        "the whole baseline (equal cost).\n\n",
        baseline->seconds, baseline->cpuSeconds, baseline->iterations, baseline->albedoMae, baseline->psnr,
        baseline->msre, baseline->cpuSeconds);
  for (const BenchSweep* sw : sweeps) {
    if (sw->fromFitSchedule) {
      md += fmt::format(
          "**{}** (`{}`, over the fit's own schedule)\n\n| value | fit took (CPU) | iterations | albedo MAE | test "
          "PSNR | MSRE | fit memory |\n| --- | --- | --- | --- | --- | --- | --- |\n",
          sw->name, sw->key);
      for (const BenchRun& r : runs)
        if (r.sweep == sw->name) md += tableRow(r.value, r, false);
      writeEndCharts(out, *sw, runs, md);
      continue;
    }
    md += fmt::format(
        "**{}** (`{}`)\n\n| value | fit time (CPU) | iterations | albedo MAE | MAE at {:.0f} CPU s | test PSNR | "
        "MSRE | fit memory |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n",
        sw->name, sw->key, baseline->cpuSeconds);
    std::vector<ChartSeries> series;
    for (const BenchRun& r : runs) {
      const bool isBase = r.sweep == "baseline" && sw->with.empty();
      if (r.sweep != sw->name && !(isBase && std::count(sw->values.begin(), sw->values.end(), baseJson[sw->key])))
        continue;
      const std::string value = isBase ? valueText(baseJson[sw->key]) + " (baseline)" : r.value;
      md += tableRow(value, r, true);
      series.push_back({value, r.curveCpuSeconds, r.curveMae});
    }
    md += fmt::format("\n![{}]({}.svg)\n\n", sw->name, sw->name);
    writeTextAtomically(out / (sw->name + ".svg"), lineChartSvg("albedo MAE vs fit cost: " + sw->name,
                                                                "CPU seconds; MAE on a log scale", series, true));
  }
  writeTextAtomically(out / "bench.md", md);
}

}  // namespace

std::vector<BenchRun> runBench(const BenchOptions& o) {
  std::vector<const BenchSweep*> sweeps;
  for (const BenchSweep& sw : benchSweeps())
    if (o.sweeps.empty() || std::count(o.sweeps.begin(), o.sweeps.end(), sw.name)) sweeps.push_back(&sw);
  for (const std::string& name : o.sweeps)
    if (std::none_of(benchSweeps().begin(), benchSweeps().end(), [&](const BenchSweep& sw) { return sw.name == name; }))
      fail("bench: no sweep named '{}'", name);
  Evaluation ev;
  ev.work = o.work.empty() ? prepareDemoCapture(o.scratch).work : o.work;
  ev.testSpp = o.testSpp;
  const fs::path capture = capturePreparedIn(ev.work);
  const fs::path truth = !o.truth.empty() ? o.truth : capture / "gt" / "scene.json";
  if (pathExists(truth)) {
    ev.truth = loadSceneFile(truth);
    ev.coverage = readImage(ev.work / "coverage.exr");
  } else {
    spdlog::warn("bench: no ground truth ({}): albedo errors are not measured", truth.string());
  }
  ev.testCameras = !o.testCameras.empty() ? o.testCameras : capture / "transforms_test.json";
  if (!pathExists(ev.testCameras)) ev.testCameras.clear();
  createDirectories(o.out);

  std::vector<BenchRun> runs;
  auto run = [&](const std::string& sweep, const std::string& value, const FitConfig& c) {
    spdlog::info("bench: {} = {}", sweep, value);
    // A budget's run is timed as `relume fit` runs: no evaluation inside its clock.
    BenchRun r = benchRun(ev.work, c, ev, c.timeBudget > 0 ? 0 : o.evaluateEvery);
    r.sweep = sweep, r.value = value;
    if (sweep == "baseline")
      r.maeAtBaselineCost = r.albedoMae;
    else if (!runs.empty() && runs.front().sweep == "baseline")
      r.maeAtBaselineCost = errorAt(r, runs.front().cpuSeconds);
    spdlog::info("bench: {} = {}: {:.0f} s ({:.0f} CPU s), albedo MAE {:.4f}{}, test PSNR {:.2f} dB", sweep, value,
                 r.seconds, r.cpuSeconds, r.albedoMae,
                 std::isfinite(r.maeAtBaselineCost) ? fmt::format(" ({:.4f} at the baseline's cost)", r.maeAtBaselineCost)
                                                    : std::string(),
                 r.psnr);
    runs.push_back(std::move(r));
    writeOutputs(o.out, runs, sweeps, o.base);  // after every run: a long bench that is stopped keeps what it measured
  };
  if (std::any_of(sweeps.begin(), sweeps.end(), [](const BenchSweep* sw) { return !sw->fromFitSchedule; }))
    run("baseline", "", o.base);
  const Json baseJson = o.base.toJson();
  for (const BenchSweep* sw : sweeps)
    for (const Json& v : sw->values)
      if (v != baseJson[sw->key] || !sw->with.empty() || sw->fromFitSchedule) {
        Json change = sw->with;
        change[sw->key] = v;
        const std::string value = valueText(v) + (sw->with.empty() ? "" : " (" + sw->with.dump() + ")");
        run(sw->name, value,
            FitConfig::fromJson(change, "bench sweep " + sw->name, sw->fromFitSchedule ? o.schedule : o.base));
      }
  return runs;
}

}  // namespace relume
