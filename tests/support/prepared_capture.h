// A small synthetic capture, written and prepared in a fresh temporary folder DIR (DIR/capture,
// DIR/work) at one texture resolution. CTest runs tests in parallel processes: each names its own.
#pragma once
#include <filesystem>
#include <functional>
#include <string>

#include "product/prepare.h"
#include "scenes/synth.h"

namespace relume {

// `alter`, when given, changes the capture folder before it is prepared.
inline std::filesystem::path preparedCapture(const std::string& name, SynthCaptureOptions capture, int resolution,
                                             const std::function<void(const std::filesystem::path&)>& alter = {}) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("relume_" + name);
  std::filesystem::remove_all(dir);
  capture.out = dir / "capture";
  writeSynthCapture(capture);
  if (alter) alter(capture.out);
  PrepareOptions po;
  po.resolutions = {resolution};
  po.atlas.gutterResolution = resolution;
  prepareCapture(capture.out, dir / "work", po);
  return dir;
}

// The room, 16 frames of 64x48 at 2 spp, prepared at 128^2: the smallest capture a fit scores on
// (enough texels are observed >= 5 times).
inline std::filesystem::path smallPreparedRoom(const std::string& name) {
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 2, so.testSpp = 2,
  so.atlasResolution = 128;
  return preparedCapture(name, so, 128);
}

// The room, 16 frames of 64x48 at 8 spp, truth atlas 256^2: the known-answer fits' capture, with
// `imperfections` (scenes/imperfections.h) when given.
inline SynthCaptureOptions room256(const std::string& imperfections = "") {
  SynthCaptureOptions so;
  so.frames = 16, so.testFrames = 1, so.width = 64, so.height = 48, so.spp = 8, so.testSpp = 8;
  so.atlasResolution = 256;
  if (!imperfections.empty()) so.imperfections = parseImperfections(imperfections);
  return so;
}

// room256() prepared at 256^2.
inline std::filesystem::path preparedRoom256(const std::string& name) { return preparedCapture(name, room256(), 256); }

}  // namespace relume
