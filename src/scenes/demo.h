// `relume demo`: the whole pipeline on the built-in synthetic room, with known ground truth:
// synth -> prepare -> fit -> re-render the held-out views -> compare with the truth. Writes
// OUT/summary.json and OUT/report.md (pictures and numbers).
#pragma once
#include <filesystem>

#include "io/json.h"
#include "product/fit.h"
#include "product/report.h"
#include "scenes/synth.h"

namespace relume {

struct DemoOptions {
  std::filesystem::path out = "out/demo";
  FitConfig fit = demoFitConfig();
  // Samples per pixel of the held-out re-renders: the fit's and the truth's, with the same random
  // numbers. Against the references (captureOptions) the truth re-rendered so scores the noise
  // floor, which the demo measures and reports with the fit's score.
  int testSpp = 32;
  ReportOptions report{3, 4};  // the fit report's views: with the truth's noise cancelled, 4 spp show its errors
  static FitConfig demoFitConfig();  // reduced settings: the demo fits in a few minutes on 2 cores
  // The room's capture: synth's training frames (the fit's input), and 4 held-out views at a
  // quarter of their pixels (128x96) and 64 spp, the truth's rendering as cheap as it can be while
  // its noise stays well under the reconstruction's error seen at that scale.
  static SynthCaptureOptions captureOptions(const std::filesystem::path& capture);
};

Json runDemo(const DemoOptions& options);

// The demo's capture of the room in OUT/capture, prepared in OUT/work (each phase skipped when
// already current, so benchmarks reuse it). Returns the prepare summary.
struct DemoCapture {
  std::filesystem::path capture, work;
  double synthSeconds = 0, prepareSeconds = 0;
  size_t frames = 0;
};
DemoCapture prepareDemoCapture(const std::filesystem::path& out);

}  // namespace relume
