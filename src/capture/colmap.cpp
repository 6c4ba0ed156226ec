#include "capture/colmap.h"

#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <string_view>

#include "capture/camera_checks.h"
#include "core/error.h"
#include "io/atomic_file.h"
#include "io/input_file.h"

namespace relume {
namespace fs = std::filesystem;
namespace {

// The binary files are little-endian; relume only builds on little-endian machines.
static_assert(std::endian::native == std::endian::little, "COLMAP's binary model is little-endian");

// COLMAP's camera models by model id (colmap/sensor/models.h), for reading binary ids and naming
// the ones relume does not read.
// clang-format off
constexpr std::array<const char*, 18> kModelNames = {
    "SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV", "OPENCV_FISHEYE", "FULL_OPENCV", "FOV",
    "SIMPLE_RADIAL_FISHEYE", "RADIAL_FISHEYE", "THIN_PRISM_FISHEYE", "RAD_TAN_THIN_PRISM_FISHEYE", "SIMPLE_DIVISION",
    "DIVISION", "SIMPLE_FISHEYE", "FISHEYE", "EUCM", "EQUIRECTANGULAR"};
// clang-format on

// The models relume reads and their parameters, in COLMAP's order. "f" is one focal length for
// both axes; COLMAP's radial models are OpenCV's k1 (k) and k2.
struct SupportedModel {
  const char* name;
  std::vector<const char*> params;
};
const std::vector<SupportedModel>& supportedModels() {
  static const std::vector<SupportedModel> models = {
      {"SIMPLE_PINHOLE", {"f", "cx", "cy"}},
      {"PINHOLE", {"fx", "fy", "cx", "cy"}},
      {"SIMPLE_RADIAL", {"f", "cx", "cy", "k"}},
      {"RADIAL", {"f", "cx", "cy", "k1", "k2"}},
      {"OPENCV", {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2"}},
      {"FULL_OPENCV", {"fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"}},
  };
  return models;
}

// A camera or image as the file gives it, with `where` naming its file and entry for errors.
struct ColmapCamera {
  uint32_t id = 0;
  std::string model;
  double width = 0, height = 0;
  std::vector<double> params;
  std::string where;
};
struct ColmapImage {
  uint32_t id = 0;
  std::array<double, 4> q{};  // QW QX QY QZ: world-to-camera rotation
  std::array<double, 3> t{};  // TX TY TZ: world-to-camera translation
  uint32_t cameraId = 0;
  std::string name;
  std::string where;
};

const SupportedModel& supportedModel(const ColmapCamera& c) {
  for (const SupportedModel& m : supportedModels())
    if (c.model == m.name) return m;
  fail(
      "{}: camera model {} is not supported (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV; FULL_OPENCV "
      "with k4 = k5 = k6 = 0)",
      c.where, c.model);
}

// The field of relume's intrinsics a COLMAP parameter sets, nullptr for FULL_OPENCV's k4 k5 k6.
double* intrinsicNamed(RawIntrinsics& raw, std::string_view name) {
  static const std::pair<std::string_view, double RawIntrinsics::*> fields[] = {
      {"fx", &RawIntrinsics::fx}, {"fy", &RawIntrinsics::fy}, {"cx", &RawIntrinsics::cx}, {"cy", &RawIntrinsics::cy},
      {"k", &RawIntrinsics::k1},  {"k1", &RawIntrinsics::k1}, {"k2", &RawIntrinsics::k2}, {"p1", &RawIntrinsics::p1},
      {"p2", &RawIntrinsics::p2}, {"k3", &RawIntrinsics::k3}};
  for (const auto& [n, field] : fields)
    if (n == name) return &(raw.*field);
  return nullptr;
}

// The model's parameters onto relume's intrinsics, through the checks every camera reader shares.
Camera cameraFromColmap(const ColmapCamera& c) {
  const SupportedModel& m = supportedModel(c);
  if (c.params.size() != m.params.size())
    fail("{}: {} parameters, {} takes {} ({})", c.where, c.params.size(), c.model, m.params.size(),
         fmt::join(m.params, " "));
  RawIntrinsics raw;
  raw.width = c.width, raw.height = c.height;
  for (size_t i = 0; i < c.params.size(); ++i) {
    const std::string_view name = m.params[i];
    const double v = c.params[i];
    if (!finiteInFloat(v)) fail("{}: parameter '{}' is {}, not a finite number (in float)", c.where, name, v);
    if (name == "f") {
      raw.fx = raw.fy = v;
    } else if (double* field = intrinsicNamed(raw, name)) {
      *field = v;
    } else if (v != 0) {  // k4 k5 k6: FULL_OPENCV's rational denominator, which relume's camera has not
      fail("{}: parameter '{}' is {}; relume reads FULL_OPENCV only with k4 = k5 = k6 = 0", c.where, name, v);
    }
  }
  const bool oneFocal = m.params.front() == std::string_view("f");
  IntrinsicNames names;
  names.width = "WIDTH", names.height = "HEIGHT", names.fx = oneFocal ? "f" : "fx", names.fy = oneFocal ? "f" : "fy";
  return checkedIntrinsics(raw, names, c.where);
}

// ---- Text --------------------------------------------------------------------------------------

std::string_view trim(std::string_view s) {
  const size_t b = s.find_first_not_of(" \t\r\n");
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::vector<std::string_view> lines(std::string_view text) {
  std::vector<std::string_view> out;
  while (!text.empty()) {
    const size_t nl = text.find('\n');
    out.push_back(text.substr(0, nl));
    if (nl == std::string_view::npos) break;
    text.remove_prefix(nl + 1);
  }
  return out;
}

// Whitespace-separated tokens; `rest[i]` is the line from token i on (an image NAME may hold spaces).
struct Tokens {
  std::vector<std::string_view> tokens, rest;
};
Tokens split(std::string_view line) {
  Tokens t;
  size_t i = 0;
  while (true) {
    i = line.find_first_not_of(" \t", i);
    if (i == std::string_view::npos) break;
    const size_t end = std::min(line.find_first_of(" \t", i), line.size());
    t.tokens.push_back(line.substr(i, end - i));
    t.rest.push_back(trim(line.substr(i)));
    i = end;
  }
  return t;
}

double parseDouble(std::string_view token, const std::string& where, const char* field) {
  double v = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec != std::errc() || end != token.data() + token.size()) fail("{}: {} '{}' is not a number", where, field, token);
  return v;
}

uint64_t parseUnsigned(std::string_view token, uint64_t max, const std::string& where, const char* field) {
  uint64_t v = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec != std::errc() || end != token.data() + token.size() || v > max)
    fail("{}: {} '{}' is not an integer in [0, {}]", where, field, token, max);
  return v;
}

bool isContent(std::string_view line) { return !line.empty() && line.front() != '#'; }

std::vector<ColmapCamera> readCamerasText(const fs::path& path) {
  const std::string text = readRegularFile(path, "a COLMAP cameras.txt");
  std::vector<ColmapCamera> cameras;
  const std::vector<std::string_view> all = lines(text);
  for (size_t n = 0; n < all.size(); ++n) {
    const std::string_view line = trim(all[n]);
    if (!isContent(line)) continue;
    const std::string at = fmt::format("{}: line {}", path.string(), n + 1);
    const Tokens t = split(line);
    if (t.tokens.size() < 4) fail("{}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]", at);
    ColmapCamera c;
    c.id = static_cast<uint32_t>(parseUnsigned(t.tokens[0], UINT32_MAX, at, "CAMERA_ID"));
    c.model = std::string(t.tokens[1]);
    c.where = fmt::format("{}: camera {} ({})", at, c.id, c.model);
    c.width = static_cast<double>(parseUnsigned(t.tokens[2], UINT32_MAX, c.where, "WIDTH"));
    c.height = static_cast<double>(parseUnsigned(t.tokens[3], UINT32_MAX, c.where, "HEIGHT"));
    for (size_t i = 4; i < t.tokens.size(); ++i) c.params.push_back(parseDouble(t.tokens[i], c.where, "parameter"));
    cameras.push_back(std::move(c));
  }
  return cameras;
}

// Two lines per image: the pose line, then its 2D points (possibly empty, not read): the line after
// a pose line is always its points line, whatever it holds, as in COLMAP's own reader.
std::vector<ColmapImage> readImagesText(const fs::path& path) {
  const std::string text = readRegularFile(path, "a COLMAP images.txt");
  std::vector<ColmapImage> images;
  const std::vector<std::string_view> all = lines(text);
  static constexpr const char* kFields[] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
  for (size_t n = 0; n < all.size(); ++n) {
    const std::string_view line = trim(all[n]);
    if (!isContent(line)) continue;
    const std::string at = fmt::format("{}: line {}", path.string(), n + 1);
    const Tokens t = split(line);
    if (t.tokens.size() < 10) fail("{}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", at);
    ColmapImage im;
    im.id = static_cast<uint32_t>(parseUnsigned(t.tokens[0], UINT32_MAX, at, "IMAGE_ID"));
    im.name = std::string(t.rest[9]);
    im.where = fmt::format("{}: image {} '{}'", at, im.id, im.name);
    for (int k = 0; k < 4; ++k) im.q[k] = parseDouble(t.tokens[1 + k], im.where, kFields[k]);
    for (int k = 0; k < 3; ++k) im.t[k] = parseDouble(t.tokens[5 + k], im.where, kFields[4 + k]);
    im.cameraId = static_cast<uint32_t>(parseUnsigned(t.tokens[8], UINT32_MAX, im.where, "CAMERA_ID"));
    images.push_back(std::move(im));
    ++n;  // the points line
  }
  return images;
}

// ---- Binary ------------------------------------------------------------------------------------

// Bounds-checked little-endian reads: running off the end is an error naming the file and the field.
class ByteReader {
 public:
  ByteReader(std::string bytes, std::string file) : bytes_(std::move(bytes)), file_(std::move(file)) {}
  template <typename T>
  T read(const std::string& where, const char* field) {
    if (remaining() < sizeof(T)) fail("{}: truncated at byte {} reading {}", where, pos_, field);
    T v;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string readName(const std::string& where) {
    const size_t end = bytes_.find('\0', pos_);
    if (end == std::string::npos) fail("{}: truncated at byte {} reading NAME (no terminating null)", where, pos_);
    std::string name = bytes_.substr(pos_, end - pos_);
    pos_ = end + 1;
    return name;
  }
  // A count read from the file, each element at least `minBytes` long: bounded by what is left
  // before anything is allocated or skipped.
  uint64_t readCount(const std::string& where, const char* field, size_t minBytes) {
    const uint64_t n = read<uint64_t>(where, field);
    if (n > remaining() / minBytes)
      fail("{}: {} is {} but only {} bytes follow (at least {} each)", where, field, n, remaining(), minBytes);
    return n;
  }
  void skip(size_t n) { pos_ += n; }  // n bounded by readCount
  size_t remaining() const { return bytes_.size() - pos_; }
  void requireEnd(const char* last) const {
    if (remaining() != 0) fail("{}: {} bytes after the last {} (a count is wrong)", file_, remaining(), last);
  }
  const std::string& file() const { return file_; }

 private:
  std::string bytes_;
  std::string file_;
  size_t pos_ = 0;
};

// cameras.bin: uint64 count, then per camera uint32 CAMERA_ID, int32 MODEL_ID, uint64 WIDTH,
// uint64 HEIGHT, double params[model's count].
std::vector<ColmapCamera> readCamerasBinary(const fs::path& path) {
  ByteReader in(readRegularFile(path, "a COLMAP cameras.bin"), path.string());
  constexpr size_t kMinCamera = 4 + 4 + 8 + 8 + 3 * 8;  // SIMPLE_PINHOLE
  const uint64_t count = in.readCount(in.file(), "num_cameras", kMinCamera);
  std::vector<ColmapCamera> cameras;
  for (uint64_t i = 0; i < count; ++i) {
    ColmapCamera c;
    const std::string at = fmt::format("{}: camera #{}", in.file(), i);
    c.id = in.read<uint32_t>(at, "CAMERA_ID");
    const int32_t modelId = in.read<int32_t>(at, "MODEL_ID");
    c.model = modelId >= 0 && modelId < static_cast<int32_t>(kModelNames.size()) ? kModelNames[modelId]
                                                                                 : fmt::format("MODEL_ID {}", modelId);
    c.where = fmt::format("{}: camera {} ({})", in.file(), c.id, c.model);
    const SupportedModel& m = supportedModel(c);  // the parameter count depends on the model
    const uint64_t w = in.read<uint64_t>(c.where, "WIDTH"), h = in.read<uint64_t>(c.where, "HEIGHT");
    c.width = static_cast<double>(w), c.height = static_cast<double>(h);
    for (const char* p : m.params) c.params.push_back(in.read<double>(c.where, p));
    cameras.push_back(std::move(c));
  }
  in.requireEnd("camera");
  return cameras;
}

// images.bin: uint64 count, then per image uint32 IMAGE_ID, double QW QX QY QZ TX TY TZ, uint32
// CAMERA_ID, null-terminated NAME, uint64 num_points2D, num_points2D x (double X, double Y, int64
// POINT3D_ID) (skipped).
std::vector<ColmapImage> readImagesBinary(const fs::path& path) {
  ByteReader in(readRegularFile(path, "a COLMAP images.bin"), path.string());
  constexpr size_t kMinImage = 4 + 7 * 8 + 4 + 1 + 8, kPoint2D = 8 + 8 + 8;
  static constexpr const char* kFields[] = {"QW", "QX", "QY", "QZ", "TX", "TY", "TZ"};
  const uint64_t count = in.readCount(in.file(), "num_reg_images", kMinImage);
  std::vector<ColmapImage> images;
  for (uint64_t i = 0; i < count; ++i) {
    ColmapImage im;
    const std::string at = fmt::format("{}: image #{}", in.file(), i);
    im.id = in.read<uint32_t>(at, "IMAGE_ID");
    for (int k = 0; k < 4; ++k) im.q[k] = in.read<double>(at, kFields[k]);
    for (int k = 0; k < 3; ++k) im.t[k] = in.read<double>(at, kFields[4 + k]);
    im.cameraId = in.read<uint32_t>(at, "CAMERA_ID");
    im.name = in.readName(at);
    im.where = fmt::format("{}: image {} '{}'", in.file(), im.id, im.name);
    in.skip(in.readCount(im.where, "num_points2D", kPoint2D) * kPoint2D);
    images.push_back(std::move(im));
  }
  in.requireEnd("image");
  return images;
}

// ---- Model -> frames ---------------------------------------------------------------------------

// World-to-camera (q, t) -> camera-to-world rotation R^T and position -R^T t. A quaternion within
// kRotationTolerance of unit length is normalised (text files round it), one further off is an error.
void setPose(const ColmapImage& im, Camera& c) {
  for (double v : im.q)
    if (!std::isfinite(v))
      fail("{}: quaternion QW QX QY QZ ({} {} {} {}) is not finite", im.where, im.q[0], im.q[1], im.q[2], im.q[3]);
  for (double v : im.t)
    if (!std::isfinite(v))
      fail("{}: translation TX TY TZ ({} {} {}) is not finite", im.where, im.t[0], im.t[1], im.t[2]);
  const Eigen::Quaterniond q(im.q[0], im.q[1], im.q[2], im.q[3]);
  if (!(std::abs(q.norm() - 1.0) <= kRotationTolerance))
    fail("{}: quaternion QW QX QY QZ has norm {}, must be 1 within {}", im.where, q.norm(), kRotationTolerance);
  const Eigen::Matrix3d worldToCamera = q.normalized().toRotationMatrix();
  const Eigen::Vector3d position = -(worldToCamera.transpose() * Eigen::Vector3d(im.t[0], im.t[1], im.t[2]));
  for (int k = 0; k < 3; ++k)
    checkPositionCoordinate(position[k], im.where, fmt::format("camera position -R^T t [{}]", k));
  c.rotation = worldToCamera.transpose().cast<float>();
  c.position = position.cast<float>();
}

fs::path imagePath(const ColmapImage& im, const fs::path& images) {
  const fs::path name(im.name);
  if (im.name.empty() || name.is_absolute()) fail("{}: NAME must be a path relative to {}", im.where, images.string());
  const fs::path path = images / name;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) fail("{}: image file {} not found", im.where, path.string());
  return path;
}

struct CameraEntry {
  Camera camera;
  std::string source;
};

std::map<uint32_t, CameraEntry> camerasById(const std::vector<ColmapCamera>& cameras, const fs::path& file) {
  std::map<uint32_t, CameraEntry> byId;
  for (const ColmapCamera& c : cameras) {
    CameraEntry e{cameraFromColmap(c), fmt::format("{} (camera {})", file.string(), c.id)};
    if (!byId.emplace(c.id, std::move(e)).second) fail("{}: CAMERA_ID {} appears twice", c.where, c.id);
  }
  return byId;
}

Capture framesOf(const std::vector<ColmapCamera>& cameras, std::vector<ColmapImage> images, const fs::path& camerasFile,
                 const fs::path& imagesFile, const fs::path& imagesDir) {
  const std::map<uint32_t, CameraEntry> byId = camerasById(cameras, camerasFile);
  if (images.empty()) fail("{}: no images", imagesFile.string());
  std::set<uint32_t> ids;
  for (const ColmapImage& im : images)
    if (!ids.insert(im.id).second) fail("{}: IMAGE_ID {} appears twice", im.where, im.id);
  // Sorted by NAME: the order does not depend on COLMAP's ids, and equals a transforms.json written from it.
  std::sort(images.begin(), images.end(), [](const ColmapImage& a, const ColmapImage& b) { return a.name < b.name; });
  Capture cap;
  cap.file = imagesFile;
  cap.files = {camerasFile, imagesFile};
  for (size_t i = 0; i < images.size(); ++i) {
    const ColmapImage& im = images[i];
    if (i > 0 && im.name == images[i - 1].name) fail("{}: NAME '{}' appears twice", im.where, im.name);
    const auto cam = byId.find(im.cameraId);
    if (cam == byId.end()) fail("{}: CAMERA_ID {} is not in {}", im.where, im.cameraId, camerasFile.string());
    Frame f;
    f.camera = cam->second.camera;
    f.cameraSource = cam->second.source;
    setPose(im, f.camera);
    f.image = imagePath(im, imagesDir);
    f.exposure = 1.0f;
    f.exposureRecorded = false;
    cap.frames.push_back(std::move(f));
  }
  return cap;
}

bool bothExist(const fs::path& model, const char* ext) {
  return fs::exists(model / fmt::format("cameras.{}", ext)) && fs::exists(model / fmt::format("images.{}", ext));
}

// ---- Writer ------------------------------------------------------------------------------------

bool sameIntrinsics(const Camera& a, const Camera& b) {
  const Distortion &p = a.distortion, &q = b.distortion;
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy && a.cx == b.cx && a.cy == b.cy &&
         p.k1 == q.k1 && p.k2 == q.k2 && p.p1 == q.p1 && p.p2 == q.p2 && p.k3 == q.k3;
}

// The simplest model that holds the camera exactly, and its parameters.
std::pair<int, std::vector<double>> modelOf(const Camera& c) {
  const Distortion& d = c.distortion;
  std::vector<double> params = {c.fx, c.fy, c.cx, c.cy};
  if (!d.active()) return {1, params};  // PINHOLE
  params.insert(params.end(), {d.k1, d.k2, d.p1, d.p2});
  if (d.k3 == 0) return {4, params};  // OPENCV
  params.insert(params.end(), {d.k3, 0.0, 0.0, 0.0});
  return {6, params};  // FULL_OPENCV
}

struct WrittenImage {
  uint32_t cameraId;
  Eigen::Quaterniond q;  // world-to-camera, qw >= 0
  Eigen::Vector3d t;
  std::string name;
};

WrittenImage imageOf(const Frame& f, uint32_t cameraId, const fs::path& images) {
  const std::string name = fs::relative(f.image, images).generic_string();
  if (name.empty() || name.starts_with("..") || name.find_first_of("\n\r") != std::string::npos)
    fail("writeColmap: {} is not a file under {}", f.image.string(), images.string());
  Eigen::Quaterniond q(f.camera.rotation.cast<double>().transpose());
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1;
  const Eigen::Vector3d t = -(q.toRotationMatrix() * f.camera.position.cast<double>());
  return {cameraId, q, t, name};
}

std::string full(double v) { return fmt::format("{:.17g}", v); }

template <typename T>
void put(std::string& out, T v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

void writeText(const fs::path& model, const std::vector<Camera>& cameras, const std::vector<WrittenImage>& images) {
  std::string cams = fmt::format(
      "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      "# Number of cameras: {}\n",
      cameras.size());
  for (size_t i = 0; i < cameras.size(); ++i) {
    const auto [modelId, params] = modelOf(cameras[i]);
    cams += fmt::format("{} {} {} {}", i + 1, kModelNames[modelId], cameras[i].width, cameras[i].height);
    for (double p : params) cams += fmt::format(" {:.17g}", p);
    cams += "\n";
  }
  std::string ims = fmt::format(
      "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n# Number of images: {}\n",
      images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    const WrittenImage& im = images[i];
    ims += fmt::format("{} {} {} {} {} {} {} {} {} {}\n\n", i + 1, full(im.q.w()), full(im.q.x()), full(im.q.y()),
                       full(im.q.z()), full(im.t.x()), full(im.t.y()), full(im.t.z()), im.cameraId, im.name);
  }
  writeTextAtomically(model / "cameras.txt", cams);
  writeTextAtomically(model / "images.txt", ims);
  writeTextAtomically(model / "points3D.txt", "# 3D point list (empty: relume writes no points)\n");
}

void writeBinary(const fs::path& model, const std::vector<Camera>& cameras, const std::vector<WrittenImage>& images) {
  std::string cams;
  put<uint64_t>(cams, cameras.size());
  for (size_t i = 0; i < cameras.size(); ++i) {
    const auto [modelId, params] = modelOf(cameras[i]);
    put<uint32_t>(cams, static_cast<uint32_t>(i + 1));
    put<int32_t>(cams, modelId);
    put<uint64_t>(cams, static_cast<uint64_t>(cameras[i].width));
    put<uint64_t>(cams, static_cast<uint64_t>(cameras[i].height));
    for (double p : params) put<double>(cams, p);
  }
  std::string ims;
  put<uint64_t>(ims, images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    const WrittenImage& im = images[i];
    put<uint32_t>(ims, static_cast<uint32_t>(i + 1));
    for (double v : {im.q.w(), im.q.x(), im.q.y(), im.q.z(), im.t.x(), im.t.y(), im.t.z()}) put<double>(ims, v);
    put<uint32_t>(ims, im.cameraId);
    ims.append(im.name).push_back('\0');
    put<uint64_t>(ims, 0);  // no 2D points
  }
  std::string points;
  put<uint64_t>(points, 0);
  writeTextAtomically(model / "cameras.bin", cams);
  writeTextAtomically(model / "images.bin", ims);
  writeTextAtomically(model / "points3D.bin", points);
}

void warnAboutDroppedFields(const std::vector<Frame>& frames) {
  size_t dropped = 0;
  for (const Frame& f : frames)
    dropped += f.exposureRecorded || f.exposure != 1.0f || f.clipLow != 0.0f || std::isfinite(f.clipHigh) ||
               !f.camera.filter.isUnitBox();
  if (dropped)
    spdlog::warn("writeColmap: {} of {} frames have an exposure, clip thresholds or pixel filter COLMAP cannot hold",
                 dropped, frames.size());
}

}  // namespace

bool hasColmapModel(const fs::path& model) { return bothExist(model, "bin") || bothExist(model, "txt"); }

Capture readColmap(const fs::path& model, const fs::path& images) {
  // Cameras first, then images: an error names the first bad file.
  if (bothExist(model, "bin")) {
    const std::vector<ColmapCamera> cameras = readCamerasBinary(model / "cameras.bin");
    return framesOf(cameras, readImagesBinary(model / "images.bin"), model / "cameras.bin", model / "images.bin",
                    images);
  }
  if (bothExist(model, "txt")) {
    const std::vector<ColmapCamera> cameras = readCamerasText(model / "cameras.txt");
    return framesOf(cameras, readImagesText(model / "images.txt"), model / "cameras.txt", model / "images.txt", images);
  }
  fail("{}: no COLMAP model (expected cameras.bin + images.bin or cameras.txt + images.txt)", model.string());
}

void writeColmap(const fs::path& model, const fs::path& images, const std::vector<Frame>& frames, ColmapFormat format) {
  if (frames.empty()) fail("writeColmap: no frames to write into {}", model.string());
  warnAboutDroppedFields(frames);
  std::vector<Camera> cameras;
  std::vector<WrittenImage> written;
  for (const Frame& f : frames) {
    auto same = [&](const Camera& c) { return sameIntrinsics(c, f.camera); };
    size_t k = std::find_if(cameras.begin(), cameras.end(), same) - cameras.begin();
    if (k == cameras.size()) cameras.push_back(f.camera);
    written.push_back(imageOf(f, static_cast<uint32_t>(k + 1), images));
  }
  fs::create_directories(model);
  if (format == ColmapFormat::Text)
    writeText(model, cameras, written);
  else
    writeBinary(model, cameras, written);
}

}  // namespace relume
