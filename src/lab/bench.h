// `relume bench`: the speed/accuracy trade of the fit's settings, measured. One baseline fit, then
// one setting changed at a time (samples per ray, batch size, K frames per texel, path depth,
// gradient mode, pairing, final texture resolution, texture- vs image-space sampling). Each run
// records its wall time, the albedo error against the ground truth as the fit goes (error vs
// time), and at the end the held-out views' PSNR/MSRE. Nothing in the work folder is written.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "product/fit.h"

namespace relume {

struct BenchSweep {
  std::string name, key;  // e.g. "spp", "samples_per_ray"
  std::vector<Json> values;
  Json with = Json::object();  // other keys every value of this sweep needs (then the baseline run is not reused)
  // Runs from the fit's own schedule (BenchOptions::schedule), not the shortened base: a time budget
  // chooses the stage lengths itself, and against the shortened base every long budget would end
  // with it. Its runs are drawn against the wall clock they took (OUT/<name>_mae.svg, _psnr.svg).
  bool fromFitSchedule = false;
};
// Every sweep `relume bench` knows.
const std::vector<BenchSweep>& benchSweeps();

struct BenchOptions {
  std::filesystem::path out = "out/bench";
  std::filesystem::path work;  // a prepared work folder; empty: the demo's room, prepared in `scratch`
  std::filesystem::path scratch = "out/room";
  std::filesystem::path truth;        // ground-truth scene.json (default: CAPTURE/gt/scene.json if there)
  std::filesystem::path testCameras;  // held-out frames (default: CAPTURE/transforms_test.json if there)
  std::vector<std::string> sweeps;    // names from benchSweeps(); empty: all
  FitConfig base = baseConfig();
  FitConfig schedule;  // the fromFitSchedule sweeps' base: `relume fit`'s defaults, or --config's
  int evaluateEvery = 25;  // iterations between points of the error-vs-time curve
  int testSpp = 16;
  static FitConfig baseConfig();  // the demo's, shortened so a sweep takes minutes
};

// Costs are wall seconds and CPU seconds of the fit (evaluation excluded). Equal-cost comparisons
// and the charts use CPU seconds: on a machine shared with other work, other processes inflate
// wall time but not this process's CPU time (on an idle machine CPU ~ threads x wall).
struct BenchRun {
  std::string sweep, value;  // "baseline" for the base run
  double seconds = 0, cpuSeconds = 0;
  int iterations = 0;
  double memoryMiB = 0;  // what the fit held at its largest stage
  double albedoMae = NAN, maeAtBaselineCost = NAN, psnr = NAN, msre = NAN;
  std::vector<double> curveCpuSeconds, curveMae;
};

// Runs the baseline and every asked sweep; writes OUT/bench.csv, OUT/curves.csv, OUT/bench.md
// and one error-vs-time chart per sweep (OUT/<sweep>.svg).
std::vector<BenchRun> runBench(const BenchOptions& options);

}  // namespace relume
