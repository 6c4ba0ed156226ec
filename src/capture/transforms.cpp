#include "capture/transforms.h"

#include <cmath>

#include "capture/camera_checks.h"
#include "core/error.h"
#include "io/file_system.h"
#include "io/json.h"

namespace relume {
namespace {

// Radiance is pixel / exposure: at exposure 1e-8 a pixel of 1 is radiance 1e8, the largest a scene
// may emit (kMaxEmission, scene/appearance.h); the bound is symmetric.
constexpr double kMinExposure = 1e-8, kMaxExposure = 1e8;

struct Intrinsics {
  std::optional<double> fx, fy, cx, cy, w, h, k1, k2, p1, p2, k3, exposure, clipLow, clipHigh;
  std::optional<std::string> model;
  std::optional<PixelFilter> filter;
};

// "pixel_filter": {"type": "box" | "gaussian" | "blackman-harris", "width": pixels (optional)}.
PixelFilter readPixelFilter(const Json& j, const std::string& where) {
  if (!j.is_object() || !j.contains("type") || !j["type"].is_string())
    fail("{}: 'pixel_filter' must be an object with a string 'type'", where);
  for (const auto& [key, value] : j.items())
    if (key != "type" && key != "width") fail("{}: unknown key 'pixel_filter.{}' (type, width)", where, key);
  std::optional<double> width;
  if (j.contains("width")) {
    if (!j["width"].is_number()) fail("{}: 'pixel_filter.width' must be a number", where);
    width = j["width"].get<double>();
  }
  try {
    return PixelFilter::parse(j["type"].get<std::string>(), width);
  } catch (const Error& e) {
    fail("{}: {}", where, e.what());
  }
}

void readIntrinsics(const Json& j, Intrinsics& in, const std::string& where) {
  auto num = [&](const char* key, std::optional<double>& dst) {
    if (!j.contains(key)) return;
    // Checked in float, the precision cameras use (1e39 is finite as a double, not as a float).
    if (!j[key].is_number() || !std::isfinite(static_cast<float>(j[key].get<double>())))
      fail("{}: field '{}' must be a finite number (in float)", where, key);
    dst = j[key].get<double>();
  };
  num("fl_x", in.fx);
  num("fl_y", in.fy);
  num("cx", in.cx);
  num("cy", in.cy);
  num("w", in.w);
  num("h", in.h);
  num("k1", in.k1);
  num("k2", in.k2);
  num("p1", in.p1);
  num("p2", in.p2);
  num("k3", in.k3);
  num("exposure", in.exposure);
  num("clip_low", in.clipLow);
  num("clip_high", in.clipHigh);
  if (j.contains("pixel_filter")) in.filter = readPixelFilter(j["pixel_filter"], where);
  if (j.contains("camera_model")) {
    if (!j["camera_model"].is_string()) fail("{}: 'camera_model' must be a string", where);
    in.model = j["camera_model"].get<std::string>();
  }
}

template <typename T>
T need(const std::optional<T>& v, const char* key, const std::string& where) {
  if (!v) fail("{}: missing '{}'", where, key);
  return *v;
}

}  // namespace

static Capture parseTransforms(const std::filesystem::path& path) {
  const Json root = readJson(path);
  const std::string file = path.string();
  if (!root.is_object()) fail("{}: top level must be an object", file);
  if (!root.contains("frames") || !root["frames"].is_array()) fail("{}: missing 'frames' array", file);
  Intrinsics global;
  readIntrinsics(root, global, file);
  const Response response = root.contains("response")
                                ? Response::fromJson(root["response"], path.parent_path(), file + ": 'response'")
                                : Response();
  Capture cap;
  cap.file = path;
  cap.files = {path};
  if (root.contains("exact_poses")) {
    if (!root["exact_poses"].is_boolean()) fail("{}: 'exact_poses' must be true or false", file);
    cap.exactPoses = root["exact_poses"].get<bool>();
  }
  const auto dir = path.parent_path();
  for (size_t i = 0; i < root["frames"].size(); ++i) {
    const Json& f = root["frames"][i];
    const std::string where = fmt::format("{}: frame {}", file, i);
    if (!f.is_object()) fail("{}: must be an object", where);
    Intrinsics in = global;
    readIntrinsics(f, in, where);
    RawIntrinsics raw;
    raw.width = need(in.w, "w", where), raw.height = need(in.h, "h", where);
    raw.fx = need(in.fx, "fl_x", where), raw.fy = in.fy.value_or(raw.fx);
    raw.cx = in.cx.value_or(raw.width * 0.5), raw.cy = in.cy.value_or(raw.height * 0.5);
    const std::string model = in.model.value_or("PINHOLE");
    if (model == "OPENCV") {
      raw.k1 = in.k1.value_or(0), raw.k2 = in.k2.value_or(0), raw.p1 = in.p1.value_or(0), raw.p2 = in.p2.value_or(0),
      raw.k3 = in.k3.value_or(0);
    } else if (model != "PINHOLE") {
      fail("{}: unsupported camera_model '{}' (PINHOLE or OPENCV)", where, model);
    }
    Frame fr;
    fr.camera = checkedIntrinsics(raw, IntrinsicNames{}, where);
    fr.cameraSource = fmt::format("{} (frame {})", file, i);
    Camera& c = fr.camera;
    if (!f.contains("transform_matrix") || !f["transform_matrix"].is_array() || f["transform_matrix"].size() < 3)
      fail("{}: 'transform_matrix' must be a 4x4 (or 3x4) array", where);
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < static_cast<int>(std::min<size_t>(4, f["transform_matrix"].size())); ++r) {
      const Json& row = f["transform_matrix"][r];
      if (!row.is_array() || row.size() != 4) fail("{}: transform_matrix row {} must have 4 numbers", where, r);
      for (int k = 0; k < 4; ++k) {
        if (!row[k].is_number() || !std::isfinite(row[k].get<double>()))
          fail("{}: transform_matrix[{}][{}] is not a finite number", where, r, k);
        m(r, k) = row[k].get<double>();
      }
    }
    const Eigen::Matrix3d r = m.block<3, 3>(0, 0);
    const double offOrthonormal = (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (offOrthonormal > kRotationTolerance || std::abs(r.determinant() - 1.0) > kRotationTolerance)
      fail("{}: transform_matrix rotation is not orthonormal (det {}, |R^T R - I| {}, tolerance {})", where,
           r.determinant(), offOrthonormal, kRotationTolerance);
    for (int k = 0; k < 3; ++k)
      checkPositionCoordinate(m(k, 3), where, fmt::format("transform_matrix[{}][3] (position)", k));
    c.filter = in.filter.value_or(PixelFilter{});
    c.rotation = Camera::rotationFromOpenGL(r.cast<float>());
    c.position = m.block<3, 1>(0, 3).cast<float>();
    if (!f.contains("file_path") || !f["file_path"].is_string()) fail("{}: missing 'file_path'", where);
    fr.image = dir / f["file_path"].get<std::string>();
    if (f.contains("albedo_path")) {
      if (!f["albedo_path"].is_string()) fail("{}: 'albedo_path' must be a string", where);
      fr.albedo = dir / f["albedo_path"].get<std::string>();
    }
    fr.exposure = static_cast<float>(in.exposure.value_or(1.0));
    fr.exposureRecorded = in.exposure.has_value();
    if (!(fr.exposure >= kMinExposure && fr.exposure <= kMaxExposure))
      fail("{}: 'exposure' is {}, must be in [{:g}, {:g}]", where, fr.exposure, kMinExposure, kMaxExposure);
    if (in.clipLow) fr.clipLow = static_cast<float>(*in.clipLow);
    if (in.clipHigh) fr.clipHigh = static_cast<float>(*in.clipHigh);
    fr.response = response;
    cap.frames.push_back(fr);
  }
  if (cap.frames.empty()) fail("{}: no frames", file);
  return cap;
}

void writeTransforms(const std::filesystem::path& path, const std::vector<Frame>& frames, bool exactPoses) {
  Json root;
  root["camera_model"] = "OPENCV";
  if (exactPoses) root["exact_poses"] = true;
  const auto filterJson = [](const PixelFilter& pf) { return Json{{"type", pf.name()}, {"width", pf.width()}}; };
  const PixelFilter common = frames.empty() ? PixelFilter{} : frames.front().camera.filter;
  root["pixel_filter"] = filterJson(common);
  Json arr = Json::array();
  for (const Frame& fr : frames) {
    const Camera& c = fr.camera;
    Json f;
    if (!(c.filter == common)) f["pixel_filter"] = filterJson(c.filter);
    f["file_path"] = relativePath(fr.image, path.parent_path()).generic_string();
    if (!fr.albedo.empty()) f["albedo_path"] = relativePath(fr.albedo, path.parent_path()).generic_string();
    f["fl_x"] = c.fx;
    f["fl_y"] = c.fy;
    f["cx"] = c.cx;
    f["cy"] = c.cy;
    f["w"] = c.width;
    f["h"] = c.height;
    f["k1"] = c.distortion.k1;
    f["k2"] = c.distortion.k2;
    f["p1"] = c.distortion.p1;
    f["p2"] = c.distortion.p2;
    f["k3"] = c.distortion.k3;
    if (fr.exposureRecorded || fr.exposure != 1.0f) f["exposure"] = fr.exposure;
    if (fr.clipLow != Frame{}.clipLow) f["clip_low"] = fr.clipLow;
    if (fr.clipHigh != Frame{}.clipHigh) f["clip_high"] = fr.clipHigh;
    const Mat3 gl = c.rotationToOpenGL();
    Json m = Json::array();
    for (int r = 0; r < 3; ++r) m.push_back({gl(r, 0), gl(r, 1), gl(r, 2), c.position[r]});
    m.push_back({0, 0, 0, 1});
    f["transform_matrix"] = m;
    arr.push_back(f);
  }
  root["frames"] = arr;
  writeJson(path, root);
}

Capture readTransforms(const std::filesystem::path& path) {
  return withJsonErrors(path, [&] { return parseTransforms(path); });
}

}  // namespace relume
