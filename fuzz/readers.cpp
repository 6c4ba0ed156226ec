#include "readers.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <stdexcept>

#include "capture/colmap.h"
#include "capture/frame_store.h"
#include "capture/objects.h"
#include "capture/photometric_consistency.h"
#include "capture/response.h"
#include "capture/transforms.h"
#include "core/error.h"
#include "io/image.h"
#include "optim/checkpoint.h"
#include "product/confidence.h"
#include "product/light_decisions.h"
#include "product/time_budget.h"
#include "sampling/visibility.h"
#include "scene/appearance.h"
#include "scene/mesh.h"
#include "scene/segmentation.h"
#include "scenes/imperfections.h"

namespace relume::fuzz {
namespace fs = std::filesystem;
namespace {

// A per-process folder holding the scratch input and what fuzzed files may refer to: scene.json's
// mesh (two objects with uv) and texture.exr, the images COLMAP seeds name (images/a.png ... f.png,
// images/sub/g.png; their content is never read). Removed at exit.
struct ScratchDir {
  const fs::path path = fs::temp_directory_path() / fmt::format("relume_fuzz_{}", getpid());
  ScratchDir() {
    fs::create_directories(path);
    MeshData quad;
    quad.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    quad.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    quad.triangles = {{0, 1, 2}, {0, 2, 3}};
    quad.faceObject = {0, 1};
    writePly(path / "mesh.ply", quad);
    Image texture(2, 2);
    texture.rgb.assign(texture.rgb.size(), 0.5f);
    writeExr(path / "texture.exr", texture);
    fs::create_directories(path / "images" / "sub");
    for (const char* name : {"a.png", "b.png", "c.png", "d.png", "e.png", "f.png", "sub/g.png"})
      std::ofstream(path / "images" / name) << "placeholder";
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

const fs::path& scratchDir() {
  static const ScratchDir dir;
  return dir.path;
}

struct Reader {
  std::string fileName;  // the extension matters: mesh and image readers dispatch on it
  std::function<void(const fs::path&)> read;
};

void touchFrameStore(const fs::path& file) {
  const FrameStore store(file);
  for (size_t f = 0; f < store.frameCount(); ++f) {
    const FrameStats& s = store.stats(f);
    const float w = static_cast<float>(s.width * s.downscale), h = static_cast<float>(s.height * s.downscale);
    for (const Vec2& px : {Vec2(0.5f, 0.5f), Vec2(w / 2, h / 2), Vec2(w - 0.5f, h - 0.5f)}) (void)store.bilinear(f, px);
  }
}

void touchVisibility(const fs::path& file) {
  const VisibilityIndex v = VisibilityIndex::read(file, 64);
  uint64_t sum = 0;
  for (size_t tile = 0; tile + 1 < v.offsets.size(); ++tile)
    for (size_t k = 0; k < v.frameCount(tile); ++k) sum += v.framesOf(tile)[k];
  const size_t lastTexel = static_cast<size_t>(v.resolution) * v.resolution - 1;
  if (v.tileOf(lastTexel, v.resolution) + 1 >= v.offsets.size()) throw std::logic_error("tileOf out of range");
  (void)sum;
}

void touchCheckpoint(const fs::path& file) {
  const Checkpoint c = Checkpoint::read(file);
  (void)c.meta.dump();
  // The header fields `fit --resume` reads, each on its own so one missing field hides no other.
  for (const char* key : {"stage", "iteration", "global_iteration", "resolution", "emission_texture_resolution"}) try {
      (void)c.metaInteger(key, 0, INT32_MAX);
    } catch (const Error&) {
    }
  (void)c.bytes("albedo");
  // The per-object and per-texel records `fit --resume` reads after the parameters, sized as it
  // sizes them: objects from the emitter flags, texels from the albedo (3 floats each).
  try {
    ObjectRoles roles(static_cast<int>(std::min<size_t>(c.bytes("emitter"), 4096)));
    CheckpointIo io = CheckpointIo::reader(c);
    roles.serialise(io, file.parent_path());
  } catch (const Error&) {
  }
  try {
    SettledAlbedo settled;
    CheckpointIo io = CheckpointIo::reader(c);
    settled.serialise(io, c.bytes("albedo") / (3 * sizeof(float)), file.parent_path());
  } catch (const Error&) {
  }
  try {  // a time budget's plan, over as many stages as it lists (each 2000 iterations by default)
    const size_t count = std::min<size_t>(c.bytes("budget.lengths") / sizeof(int), 64);
    const std::vector<Stage> stages(count, Stage{"", {0}, 64, 2000});
    if (stages.empty()) return;
    TimeBudget budget(1.0, stages, std::vector<double>(stages.size(), 1.0));
    CheckpointIo io = CheckpointIo::reader(c);
    double elapsed = 0;
    budget.serialise(io, elapsed, file.string());
  } catch (const Error&) {
  }
}

// `synth --imperfect SPEC`: a spec that parses must survive its canonical form unchanged.
void parseImperfectionSpec(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  const std::string spec((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const ImperfectionSpec parsed = parseImperfections(spec);
  const std::string canonical = toString(parsed);
  if (!(parseImperfections(canonical) == parsed) || toString(parseImperfections(canonical)) != canonical)
    throw std::logic_error("imperfection spec '" + spec + "' does not round-trip through '" + canonical + "'");
}

// A response table (`prepare --response table:FILE`): one that reads must map every code to a
// finite linear value, non-decreasing in the code (the reader refuses tables that are not).
void readResponseTable(const fs::path& file) {
  const Response r = Response::parse("table:" + file.filename().string(), file.parent_path(), "fuzz");
  float previous = -INFINITY;
  for (int code = 0; code <= 65535; code += 17) {
    const float linear = r.toLinear(code / 65535.0f, false);
    if (!std::isfinite(linear) || linear < previous)
      throw std::logic_error(fmt::format("response table: code {} maps to {} after {}", code, linear, previous));
    previous = linear;
  }
}

// A COLMAP model is two files. The input is split at a 4-byte little-endian length prefix: that
// many bytes (at most what follows) are cameras.<ext>, the rest images.<ext>. One input so mutates
// both files, and a mutation of the prefix moves bytes from one to the other.
void readColmapModel(const fs::path& file, const std::string& ext) {
  std::ifstream in(file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  uint32_t cameraBytes = 0;
  std::memcpy(&cameraBytes, bytes.data(), std::min<size_t>(4, bytes.size()));
  const std::string rest = bytes.size() > 4 ? bytes.substr(4) : std::string();
  const size_t split = std::min<size_t>(cameraBytes, rest.size());
  const fs::path model = scratchDir() / ("colmap_" + ext);
  fs::create_directories(model);
  std::ofstream(model / ("cameras." + ext), std::ios::binary) << rest.substr(0, split);
  std::ofstream(model / ("images." + ext), std::ios::binary) << rest.substr(split);
  const Capture cap = readColmap(model, scratchDir() / "images");
  for (const Frame& f : cap.frames) {  // what prepare does with a camera first: project and cast rays
    const Camera& c = f.camera;
    (void)c.project(c.position + c.rotation.col(2));
    (void)c.rayDirection(Vec2(0.5f * c.width, 0.5f * c.height));
  }
}

// segments.bin for a mesh of as many faces as the file has ids after its 16-byte header, so the
// fuzzer reaches the ids; the object count prepare derives from them must then be in range.
void readFaceObjectsFile(const fs::path& file) {
  const uintmax_t size = fs::file_size(file);
  const size_t faces = size > 16 ? static_cast<size_t>((size - 16) / 4) : 1;
  const std::vector<int32_t> ids = readFaceObjects(file, faces);
  const int32_t objects = 1 + *std::max_element(ids.begin(), ids.end());
  if (ids.size() != faces || objects < 1 || static_cast<size_t>(objects) > faces)
    throw std::logic_error(fmt::format("segments: {} ids, {} objects for {} faces", ids.size(), objects, faces));
}

// frame_gains.json for a capture of 8 frames: every gain read must be positive and finite.
void readFrameGains(const fs::path& file) {
  for (const Color& g : readConsistencyGains(file, 8))
    if (!(isFinite(g) && (g > 0.0f).all())) throw std::logic_error("frame gains: a gain not positive and finite");
}

const std::map<std::string, Reader>& readers() {
  static const std::map<std::string, Reader> table = {
      {"ply", {"input.ply", [](const fs::path& f) { (void)loadMesh(f); }}},
      {"obj", {"input.obj", [](const fs::path& f) { (void)loadMesh(f); }}},
      {"transforms", {"transforms.json", [](const fs::path& f) { (void)readTransforms(f); }}},
      {"colmap-text", {"colmap_text.model", [](const fs::path& f) { readColmapModel(f, "txt"); }}},
      {"colmap-binary", {"colmap_binary.model", [](const fs::path& f) { readColmapModel(f, "bin"); }}},
      {"objects", {"objects.json", [](const fs::path& f) { (void)readObjectNames(f); }}},
      {"scene", {"scene.json", [](const fs::path& f) { (void)loadSceneFile(f); }}},
      {"image", {"input.exr", [](const fs::path& f) { (void)readImage(f); }}},
      {"frames", {"frames.bin", touchFrameStore}},
      {"visibility", {"visibility.bin", touchVisibility}},
      {"checkpoint", {"checkpoint.bin", touchCheckpoint}},
      {"imperfections", {"imperfections.txt", parseImperfectionSpec}},
      {"response-table", {"response.txt", readResponseTable}},
      {"segments", {"segments.bin", readFaceObjectsFile}},
      {"frame-gains", {"frame_gains.json", readFrameGains}},
  };
  return table;
}

}  // namespace

std::vector<std::string> readerNames() {
  std::vector<std::string> names;
  for (const auto& [name, reader] : readers()) names.push_back(name);
  return names;
}

void readBytes(const std::string& name, const uint8_t* data, size_t size) {
  const auto it = readers().find(name);
  if (it == readers().end()) throw std::invalid_argument("no reader named " + name);
  const fs::path file = scratchDir() / it->second.fileName;
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  try {
    it->second.read(file);
  } catch (const Error&) {
    // Bad input, reported as it should be.
  }
}

}  // namespace relume::fuzz
