// Procedural scenes whose ground truth we control, and complete synthetic captures of them.
#pragma once
#include <filesystem>
#include <string>

#include "capture/transforms.h"
#include "render/path_tracer.h"
#include "scene/appearance.h"
#include "scenes/imperfections.h"

namespace relume {

// Scan: the room as a noisy, densely tessellated mesh without uv (a stand-in for a real scan;
// per-object albedo constants), for scale tests of `prepare`.
// Lounge: the room's shell furnished to test light-source decisions: two window panes (light
// sources), a pendant lamp over a glossy red table, a white sofa (albedo 0.95) and a white cabinet
// (0.92) that a dim albedo init would make look emissive.
enum class SynthSceneKind { Room, Cornell, Furnace, Scan, Lounge };
SynthSceneKind parseSynthScene(const std::string& name);  // throws relume::Error

struct SynthScene {
  SynthSceneKind kind;
  SceneDescription scene;  // mesh with a uv atlas; appearance with the true parameters
};

// Builds the scene in memory. atlasResolution sets the ground-truth albedo texture size;
// scanTriangles the size of the Scan mesh.
SynthScene makeSynthScene(SynthSceneKind kind, int atlasResolution = 1024, size_t scanTriangles = 1000000);

// The room tessellated to about `targetTriangles` with every vertex displaced by up to
// `noiseMetres` (a function of its position, so shared vertices stay shared): a stand-in for a
// scanned mesh. No uv.
TriangleMesh makeScanLikeRoom(size_t targetTriangles, float noiseMetres);

// A smooth hand-held-like walk that sees every wall, the floor and the lights. `phase` in [0,1)
// shifts the walk, so test views differ from training views.
std::vector<Camera> synthCameraPath(SynthSceneKind kind, int frames, int width, int height, double phase);

struct SynthCaptureOptions {
  SynthSceneKind kind = SynthSceneKind::Room;
  std::filesystem::path out;
  int frames = 24, testFrames = 4;
  int width = 256, height = 192;
  int spp = 16;
  // The held-out frames are the references re-renders are scored against, as a photo would be:
  // rendered near convergence, so that their noise does not cap the score (at 16 spp the ground
  // truth itself scores 30.5 dB against them).
  int testSpp = 256;
  int testWidth = 0, testHeight = 0;  // the held-out frames' size (0: the frames' own)
  int maxDepth = kDefaultMaxDepth;
  uint64_t seed = 1;
  bool withUv = false;
  int atlasResolution = 1024;
  size_t scanTriangles = 1000000;
  PixelFilter pixelFilter;  // the frames' pixel filter (box: relume's own; Cycles' default: Blackman-Harris 1.5)
  // A hand-held camera's flaws in the training frames, their truth in gt/imperfections.json
  // (scenes/imperfections.h). Absent: the clean capture, byte for byte as before.
  std::optional<ImperfectionSpec> imperfections;
};

// Writes mesh.ply, objects.json, transforms.json, transforms_test.json, images/, test/, gt/
// (scene.json, textures, uv-mapped mesh; with imperfections also imperfections.json and, with mesh
// noise, mesh_clean.ply). Returns the number of rendered frames.
int writeSynthCapture(const SynthCaptureOptions& options);

}  // namespace relume
