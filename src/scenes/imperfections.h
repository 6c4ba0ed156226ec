// The flaws of a hand-held capture, for `relume synth --imperfect SPEC`: wrong poses, bracketed and
// drifting exposure, white balance, sensor noise, 8/16-bit sRGB frames, a noisy scanned mesh, no
// segmentation and missing frames. Each is applied to the training frames only (the held-out
// frames are the judge and stay clean) and its truth is written to gt/imperfections.json, so the
// cost of every flaw can be measured against the clean capture of the same seed.
// Every random draw comes from a stream of its own (core/random_streams.h) keyed by the synth
// seed and the frame index, so the same spec and seed give byte-identical captures.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "capture/transforms.h"
#include "core/camera.h"
#include "io/image.h"
#include "io/json.h"
#include "io/mesh_data.h"

namespace relume {

// A number with the unit it was given in (kept, so that toString gives back what was written).
struct Length {
  double value = 0;
  std::string unit = "m";  // mm, cm or m
  double metres() const;
  bool operator==(const Length&) const = default;
};
struct Angle {
  double value = 0;
  std::string unit = "rad";  // deg or rad
  double radians() const;
  bool operator==(const Angle&) const = default;
};

struct PoseError {
  Length translation;  // every written position is this far from the true one
  Angle rotation;      // every written orientation is turned by this angle
  bool operator==(const PoseError&) const = default;
};

struct SensorNoise {
  double photons = 0;    // photons collected at radiance 1 (after exposure and gains)
  double readSigma = 0;  // Gaussian read noise, in the same units as radiance
  bool operator==(const SensorNoise&) const = default;
};

// An absent field is a flaw the capture does not have.
struct ImperfectionSpec {
  std::optional<PoseError> pose;
  std::vector<double> bracketStops;      // frame i exposed at 2^stops[i mod n] (recorded)
  std::optional<double> whiteBalance;    // sigma of each channel's log gain (not recorded)
  std::optional<double> exposureDrift;   // sigma of the frame's log gain (not recorded)
  std::optional<SensorNoise> noise;      // shot and read noise
  std::optional<int> ldrBits;            // 8 or 16: sRGB PNG frames clipped at 1
  std::optional<Length> meshNoise;       // every vertex of mesh.ply moved by at most this
  bool segmentation = true;              // false: no objects.json, no object ids in mesh.ply
  std::optional<double> missingPercent;  // this share of the training frames left out
  std::string absentObject;              // this object left out of mesh.ply (a scan that missed it); "": none
  std::string unseenObject;  // every training frame that shows this object left out (a light no frame shows)
  bool operator==(const ImperfectionSpec&) const = default;
};

// "key=value;key=value...", keys pose, bracket, wb, exposure-drift, noise, ldr, mesh, segmentation,
// missing, absent, unseen (docs/user/commands.md#imperfect-captures). An empty spec has no flaw. Throws a
// one-line relume::Error naming the key and what is allowed.
ImperfectionSpec parseImperfections(std::string_view spec);
// The canonical spec: parseImperfections(toString(s)) == s.
std::string toString(const ImperfectionSpec& spec);

// What was done to one training frame.
struct FrameImperfection {
  int index = 0;          // in the clean capture's walk (its image keeps this number)
  bool leftOut = false;   // not in the capture
  bool showsUnseen = false;  // it shows the `unseen` object (and is left out for it)
  Camera truePose;        // where the frame was rendered from
  Camera writtenPose;     // what transforms.json says
  float exposure = 1.0f;  // 2^stop, recorded in transforms.json when bracketing
  bool exposureRecorded = false;
  Color whiteBalance = Color::Ones();  // per-channel gain, not recorded
  float exposureDrift = 1.0f;          // scalar gain, not recorded
};

// The id `objectNames` gives object `name` (for `key`); throws relume::Error naming the objects.
int32_t namedObject(std::string_view key, const std::string& name, const std::vector<std::string>& objectNames);
// Per camera: whether the first surface one of its pixel centres sees on `mesh` is object `object`.
std::vector<uint8_t> camerasShowing(const MeshData& mesh, int32_t object, const std::vector<Camera>& cameras);

// One entry per camera of the training walk; `showsUnseen` (per camera, empty without `unseen`):
// camerasShowing the unseen object. Throws relume::Error if `missing` and `unseen` leave no frame.
std::vector<FrameImperfection> planFrameImperfections(const ImperfectionSpec& spec, const std::vector<Camera>& walk,
                                                      uint64_t seed, const std::vector<uint8_t>& showsUnseen = {});
// Turns a rendered radiance image into what the sensor records, in place: times exposure, drift and
// white balance, then shot and read noise, then clamped at 0 (and at 1 for ldr frames).
void applySensor(const ImperfectionSpec& spec, const FrameImperfection& frame, uint64_t seed, Image& image);
// Moves every vertex by a random offset of length at most `noise` (uniform in the ball), a function
// of the seed and the vertex position, so coincident vertices move together. Returns the largest offset.
double displaceVertices(MeshData& mesh, const Length& noise, uint64_t seed);

// A training frame as the flawed camera delivers it: applySensor on the true radiance, written as
// `exrPath` or, for ldr frames, the PNG beside it (the other one removed), under the written pose and
// recorded exposure. Returns the frame as transforms.json lists it.
Frame writeFlawedFrame(const ImperfectionSpec& spec, const FrameImperfection& frame, uint64_t seed,
                       const std::filesystem::path& exrPath, Image radiance);
// A capture's mesh.ply in `folder` as a scanner would give it: with mesh noise the vertices
// displaced, with an absent object its faces left out (either way the given mesh kept as
// gt/mesh_clean.ply), without segmentation no object ids. `objectNames` name the mesh's object ids.
// Returns the largest vertex offset. Throws relume::Error naming an absent object the mesh lacks.
double writeFlawedMesh(const ImperfectionSpec& spec, MeshData mesh, const std::vector<std::string>& objectNames,
                       const std::filesystem::path& folder, uint64_t seed);

// gt/imperfections.json: the spec (as written and as values) and every training frame's truth.
Json imperfectionsJson(const ImperfectionSpec& spec, uint64_t seed, const std::vector<FrameImperfection>& frames,
                       double largestVertexOffset);
// Camera-to-world in the transforms.json convention (OpenGL axes), as rows.
Json cameraToWorldJson(const Camera& camera);

}  // namespace relume
