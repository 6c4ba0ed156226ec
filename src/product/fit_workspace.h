// What the fit works on: everything `prepare` wrote to WORK, loaded and checked once, and the
// albedo texels of one resolution (which may be sampled, which updated).
#pragma once
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "capture/frame_store.h"
#include "capture/transforms.h"
#include "io/image.h"
#include "io/json.h"
#include "sampling/samplers.h"
#include "sampling/visibility.h"
#include "scene/mesh.h"
#include "scene/scene.h"
#include "scene/texel_map.h"

namespace relume {

// Everything prepare built, loaded once; every missing or inconsistent file is a one-line error.
struct Workspace {
  std::filesystem::path dir;
  Json prepare;
  TriangleMesh mesh;
  std::unique_ptr<Scene> scene;
  std::vector<Frame> frames;  // their poses as the fit has refined them (frame_poses.h)
  bool exactPoses = false;    // the capture says its poses are exact (Capture::exactPoses)
  std::unique_ptr<FrameStore> store;
  VisibilityIndex vis;
  int initResolution = 0;
  std::vector<int> resolutions;
  std::vector<float> coverage;                     // observations per texel at the init resolution
  std::vector<std::pair<int, std::string>> names;  // object id, name
  std::vector<uint32_t> kept;

  explicit Workspace(const std::filesystem::path& work);

  // Observations of the init-resolution texel that contains texel t of a `res` map.
  float coverageOf(size_t t, int res) const;
  TrainingFrames trainingFrames() const { return {&frames, store.get(), kept}; }
  // Per frame, the gains prepare found in the frames' agreement (frame_gains.json; 1 where none).
  std::vector<Color> consistencyGains() const;
  // Prepare's median radiance per texel at the init resolution (albedo_init.exr).
  Image medianRadiance() const;
  // The resolution the frames resolve: the smallest prepared resolution whose texel is no larger
  // than the median footprint on the surface of the pixels of `batch`'s rays.
  int resolvedResolution(const Batch& batch) const;
};

// The albedo texels of one resolution: the texel map, which texels may be sampled (covered and
// observed) and which may be updated (also the dilated ring, read by bilinear lookups).
struct TexelSpace {
  int resolution = 0;
  TexelMap map;
  std::vector<uint32_t> sampleable;
  std::vector<uint8_t> updatable;
  // Texels of `excluded` objects (out of the model: light_evidence.h) are neither sampled nor updated.
  TexelSpace(const Workspace& w, int res, const std::vector<uint8_t>& excluded = {});
  int objectOf(size_t texel, const TriangleMesh& mesh) const { return mesh.faceObject[map.triangle(texel)]; }
  // The sampleable texels of each of `objectCount` objects.
  std::vector<std::vector<uint32_t>> sampleableByObject(const TriangleMesh& mesh, int objectCount) const;
};

}  // namespace relume
