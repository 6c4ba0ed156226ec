// A small synthetic capture, written and prepared in a fresh temporary folder DIR (DIR/capture,
// DIR/work) at one texture resolution. CTest runs tests in parallel processes: each names its own.
#pragma once
#include <filesystem>
#include <string>

#include "pipeline/prepare.h"
#include "pipeline/synth.h"

namespace relume {

inline std::filesystem::path preparedCapture(const std::string& name, SynthCaptureOptions capture, int resolution) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("relume_" + name);
  std::filesystem::remove_all(dir);
  capture.out = dir / "capture";
  writeSynthCapture(capture);
  PrepareOptions po;
  po.resolutions = {resolution};
  po.atlas.gutterResolution = resolution;
  prepareCapture(capture.out, dir / "work", po);
  return dir;
}

}  // namespace relume
