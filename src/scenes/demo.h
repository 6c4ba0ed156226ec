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
  // numbers. The truth so re-rendered scores the noise floor against the references
  // (captureOptions), which the demo measures and reports beside the fit's score; against the
  // truth, the fit's common noise cancels.
  int testSpp = 16;
  // The fit report's views: the fit and the truth at 4 spp with the same random numbers, the error
  // per 4x4 pixels; on the demo its noise is below the reconstruction's error (report captions).
  ReportOptions report{3, 4};
  static FitConfig demoFitConfig();  // reduced settings: the demo fits in a few minutes on 2 cores
  // The room's capture: synth's training frames (the fit's input) and 4 held-out views at a
  // quarter of their pixels (128x96) and 32 spp, which with their re-renders take about 10 s on 2
  // cores: converged references (256x192 at 256 spp, 128-spp re-renders) would take 3.5 minutes,
  // and the demo keeps to 3. Their noise is measured instead (the noise floor).
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
