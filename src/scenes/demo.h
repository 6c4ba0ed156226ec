// `relume demo`: the whole pipeline on the built-in synthetic room, with known ground truth:
// synth -> prepare -> fit -> re-render the held-out views -> compare with the truth. Writes
// OUT/summary.json and OUT/report.md (pictures and numbers).
#pragma once
#include <filesystem>

#include "io/json.h"
#include "product/fit.h"

namespace relume {

struct DemoOptions {
  std::filesystem::path out = "out/demo";
  FitConfig fit = demoFitConfig();
  // Samples per pixel of the held-out re-renders. The references are rendered at 256 spp
  // (SynthCaptureOptions::testSpp): the ground truth re-rendered at 128 spp scores 38.6 dB against
  // them; against 16-spp references (as the training frames) it scored 30.5 dB at 64 spp, their
  // noise alone.
  int testSpp = 128;
  static FitConfig demoFitConfig();  // reduced settings: the demo fits in a few minutes on 2 cores
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
