#include "scenes/degrade.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "capture/capture_folder.h"
#include "capture/frame_image.h"
#include "capture/objects.h"
#include "core/error.h"
#include "io/file_system.h"
#include "io/json.h"

namespace fs = std::filesystem;

namespace relume {
namespace {

void checkOutputFolder(const DegradeOptions& o) {
  if (!pathExists(o.out)) return;
  std::error_code ec;
  if (fs::equivalent(o.out, o.capture, ec))
    fail("{}: degrade writes a new capture; --out must not be the source capture", o.out.string());
  if (!isDirectory(o.out)) fail("{}: exists and is not a folder", o.out.string());
  if (!fs::is_empty(o.out, ec))
    fail("{}: not empty (degrade writes a new capture into an empty folder)", o.out.string());
}

// A path the capture names relative to its folder, that stays inside it.
fs::path insideFolder(const fs::path& folder, const fs::path& file, const fs::path& named) {
  const fs::path relative = relativePath(file, folder);
  if (relative.empty() || relative.is_absolute() || *relative.begin() == "..")
    fail("{}: '{}' lies outside the capture folder; degrade copies only what is inside it", named.string(),
         file.string());
  return relative;
}

// The held-out frames, unchanged: transforms_test.json byte for byte and every image it names
// (the frames and their albedo passes) at the same place in `out`.
int copyHeldOut(const fs::path& capture, const fs::path& out) {
  const fs::path json = capture / "transforms_test.json";
  if (!pathExists(json)) return 0;
  const Capture heldOut = readTransforms(json);
  for (const Frame& f : heldOut.frames)
    for (const fs::path& image : {f.image, f.albedo}) {
      if (image.empty()) continue;
      const fs::path relative = insideFolder(capture, image, json);
      createDirectories((out / relative).parent_path());
      copyFileOver(image, out / relative);
    }
  copyFileOver(json, out / "transforms_test.json");
  return static_cast<int>(heldOut.frames.size());
}

// The source's ground truth, if it has one, as it is.
void copyTruth(const fs::path& capture, const fs::path& out) {
  const fs::path gt = capture / "gt";
  if (!isDirectory(gt)) return;
  std::error_code ec;
  fs::copy(gt, out / "gt", fs::copy_options::recursive, ec);
  if (ec) fail("{}: cannot copy to {}: {}", gt.string(), (out / "gt").string(), ec.message());
}

// objects.json as the source names its segments (its own file, or the OBJ's groups).
void writeObjectNames(const fs::path& capture, const MeshData& mesh, const fs::path& out) {
  if (pathExists(capture / "objects.json")) {
    (void)readObjectNames(capture / "objects.json");  // a malformed file is the source's error, named
    copyFileOver(capture / "objects.json", out / "objects.json");
    return;
  }
  if (mesh.objectNames.empty()) return;
  Json objects = Json::array();
  for (size_t id = 0; id < mesh.objectNames.size(); ++id)
    objects.push_back({{"id", id}, {"name", mesh.objectNames[id]}});
  writeJson(out / "objects.json", Json{{"objects", objects}});
}

// The names of the mesh's object ids (for `absent`): objects.json's, else the mesh file's.
std::vector<std::string> objectNamesOf(const fs::path& capture, const MeshData& mesh) {
  if (!pathExists(capture / "objects.json")) return mesh.objectNames;
  const int32_t objects =
      mesh.faceObject.empty() ? 1 : 1 + *std::max_element(mesh.faceObject.begin(), mesh.faceObject.end());
  std::vector<std::string> names(static_cast<size_t>(objects));
  for (const auto& [id, name] : readObjectNames(capture / "objects.json"))
    if (id >= 0 && id < objects) names[static_cast<size_t>(id)] = name;
  return names;
}

// Everything but the checks that need the frames' pixels, which writeDegraded makes as it goes.
void checkInputs(const DegradeOptions& o) {
  checkOutputFolder(o);
  if (const fs::path flaws = o.capture / "gt" / "imperfections.json"; pathExists(flaws))
    fail("{}: the capture has flaws already; degrade a clean capture", flaws.string());
}

DegradeSummary writeDegraded(const DegradeOptions& o, const Capture& source, const MeshData& mesh,
                             const std::vector<FrameImperfection>& plan) {
  DegradeSummary summary;
  createDirectories(o.out / "images");
  copyTruth(o.capture, o.out);
  std::vector<Frame> written;
  for (size_t i = 0; i < source.frames.size(); ++i) {
    if (plan[i].leftOut) {
      ++summary.framesLeftOut;
      continue;
    }
    FrameImage radiance = loadFrame(source.frames[i]);
    if (radiance.read.bits)
      fail("{}: a {}-bit frame is clipped and quantised already; degrade needs linear float frames (EXR)",
           source.frames[i].image.string(), radiance.read.bits);
    // Masked pixels (non-finite in the file) have no radiance to expose; the sensor sees black there.
    for (float& v : radiance.image.rgb)
      if (v < 0) v = 0, ++summary.maskedPixels;
    written.push_back(writeFlawedFrame(o.spec, plan[i], o.seed, o.out / "images" / fmt::format("frame_{:04d}.exr", i),
                                       radiance.image));
    ++summary.framesWritten;
  }
  writeTransforms(o.out / "transforms.json", written, source.exactPoses && !o.spec.pose);
  const double largestVertexOffset = writeFlawedMesh(o.spec, mesh, objectNamesOf(o.capture, mesh), o.out, o.seed);
  if (o.spec.segmentation) writeObjectNames(o.capture, mesh, o.out);
  summary.heldOutCopied = copyHeldOut(o.capture, o.out);
  writeJson(o.out / "gt" / "imperfections.json", imperfectionsJson(o.spec, o.seed, plan, largestVertexOffset));
  if (summary.maskedPixels)
    spdlog::warn("{}: {} masked (non-finite) pixel channels of the source written as 0", o.capture.string(),
                 summary.maskedPixels);
  return summary;
}

}  // namespace

DegradeSummary degradeCapture(const DegradeOptions& o) {
  checkInputs(o);
  const Capture source = readCapture(o.capture);
  std::vector<Camera> walk;
  for (const Frame& f : source.frames) walk.push_back(f.camera);
  const MeshData mesh = readMesh(findCaptureMesh(o.capture));
  const std::vector<uint8_t> showsUnseen =
      o.spec.unseenObject.empty()
          ? std::vector<uint8_t>{}
          : camerasShowing(mesh, namedObject("unseen", o.spec.unseenObject, objectNamesOf(o.capture, mesh)), walk);
  const std::vector<FrameImperfection> plan = planFrameImperfections(o.spec, walk, o.seed, showsUnseen);
  try {
    return writeDegraded(o, source, mesh, plan);
  } catch (...) {
    std::error_code ec;
    fs::remove_all(o.out, ec);  // it was absent or empty: no half capture is left to be prepared
    throw;
  }
}

}  // namespace relume
