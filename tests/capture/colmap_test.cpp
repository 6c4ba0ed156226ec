// COLMAP input: conventions proven by projection, exact round trips between text, binary and
// transforms.json, identical prepare outputs whichever form a capture comes in, and one-line
// errors naming the file and the field for every bad input.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>

#include "capture/capture_folder.h"
#include "capture/colmap.h"
#include "capture/frame_image.h"
#include "core/error.h"
#include "io/image.h"
#include "io/mesh_data.h"
#include "product/prepare.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path freshDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("relume_colmap_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void writeFile(const fs::path& path, const std::string& bytes) {
  fs::create_directories(path.parent_path());
  std::ofstream(path, std::ios::binary) << bytes;
}

std::string readFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Camera-to-world rotation (OpenCV axes) looking from `eye` at `target`, rolled about its axis.
Mat3 lookAt(const Vec3& eye, const Vec3& target, float roll) {
  const Vec3 z = (target - eye).normalized();
  const Vec3 x = z.cross(Vec3(0, 1, 0)).normalized();
  Mat3 r;
  r.col(0) = x, r.col(1) = z.cross(x), r.col(2) = z;
  return r * Eigen::AngleAxisf(roll, Vec3(0, 0, 1)).toRotationMatrix();
}

// Five cameras around the origin: a pinhole with fx != fy, OpenCV distortion, k3 (FULL_OPENCV),
// two sharing intrinsics. Named out of order so that reading sorts them. Images are placeholders.
std::vector<Frame> testFrames(const fs::path& images) {
  std::vector<Frame> frames;
  const char* names[] = {"c.exr", "a.exr", "sub/e.exr", "b.exr", "d.exr"};
  for (int i = 0; i < 5; ++i) {
    Frame f;
    Camera& c = f.camera;
    c.width = 64, c.height = 48, c.fx = 55.5f + i, c.fy = 57.25f, c.cx = 31.7f, c.cy = 24.2f;
    if (i == 1 || i == 3) c.distortion = {-0.05f, 0.01f, 0.002f, -0.001f, 0};
    if (i == 2) c.distortion = {0.03f, -0.02f, 0, 0.001f, 0.004f};
    if (i == 4) c.fx = 55.5f;  // the intrinsics of camera 0 again
    const float a = 0.9f * static_cast<float>(i);
    c.position = Vec3(3.0f * std::cos(a), 0.3f * i - 0.5f, 3.0f * std::sin(a));
    c.rotation = lookAt(c.position, Vec3(0.05f, -0.02f, 0.01f), 0.2f * i - 0.3f);
    f.image = images / names[i];
    writeFile(f.image, "placeholder");
    frames.push_back(f);
  }
  return frames;
}

// World points within 0.4 m of the origin, in front of every test camera.
std::vector<Vec3> knownPoints() {
  std::vector<Vec3> points;
  for (int x = -1; x <= 1; ++x)
    for (int y = -1; y <= 1; ++y)
      for (int z = -1; z <= 1; ++z) points.emplace_back(0.4f * x, 0.4f * y, 0.4f * z);
  return points;
}

const Frame& byImage(const Capture& cap, const fs::path& image) {
  for (const Frame& f : cap.frames)
    if (f.image == image) return f;
  throw std::runtime_error("no frame for " + image.string());
}

void expectSameIntrinsics(const Camera& a, const Camera& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.fy, b.fy);
  EXPECT_EQ(a.cx, b.cx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.distortion.k1, b.distortion.k1);
  EXPECT_EQ(a.distortion.k2, b.distortion.k2);
  EXPECT_EQ(a.distortion.p1, b.distortion.p1);
  EXPECT_EQ(a.distortion.p2, b.distortion.p2);
  EXPECT_EQ(a.distortion.k3, b.distortion.k3);
}

// Every field, bit for bit.
void expectIdentical(const Frame& a, const Frame& b) {
  expectSameIntrinsics(a.camera, b.camera);
  EXPECT_TRUE(a.camera.rotation == b.camera.rotation) << a.camera.rotation << "\n" << b.camera.rotation;
  EXPECT_TRUE(a.camera.position == b.camera.position);
  EXPECT_EQ(a.camera.filter, b.camera.filter);
  EXPECT_EQ(a.image, b.image);
  EXPECT_EQ(a.exposure, b.exposure);
  EXPECT_EQ(a.exposureRecorded, b.exposureRecorded);
}

}  // namespace

// COLMAP's convention by hand, independent of relume's writer: images.txt holds world-to-camera
// (x_cam = R x_world + t). A quaternion of 90 degrees about +y with t = (0, 0, 2) puts the camera at
// -R^T t = (2, 0, 0) looking along world -x; OpenCV axes (y down) and COLMAP's pixel centres at +0.5.
TEST(Colmap, HandWrittenModelFollowsCOLMAPConventions) {
  const fs::path dir = freshDir("hand");
  writeFile(dir / "images" / "f.png", "placeholder");
  writeFile(dir / "sparse" / "0" / "cameras.txt", "1 PINHOLE 64 48 50 60 32 24\n");
  const double h = std::sqrt(0.5);
  writeFile(dir / "sparse" / "0" / "images.txt", fmt::format("1 {} 0 {} 0 0 0 2 1 f.png\n\n", h, h));
  const Capture cap = readColmap(dir / "sparse" / "0", dir / "images");
  ASSERT_EQ(cap.frames.size(), 1u);
  const Camera& c = cap.frames[0].camera;
  EXPECT_TRUE(c.position.isApprox(Vec3(2, 0, 0), 1e-6f)) << c.position.transpose();
  EXPECT_TRUE(c.rotation.col(2).isApprox(Vec3(-1, 0, 0), 1e-6f)) << c.rotation;  // forward
  // A point behind the camera has no pixel: NaN fails every comparison.
  const auto pixel = [&](const Vec3& p) { return c.project(p).value_or(Vec2::Constant(NAN)); };
  EXPECT_TRUE(pixel(Vec3(0, 0, 0)).isApprox(Vec2(32, 24), 1e-6f));  // ahead: principal point
  // R maps world +z onto camera +x: a point 0.2 m along +z, 2 m ahead, is 50 * 0.1 = 5 px right.
  EXPECT_TRUE(pixel(Vec3(0, 0, 0.2f)).isApprox(Vec2(37, 24), 1e-6f)) << pixel(Vec3(0, 0, 0.2f)).transpose();
  EXPECT_TRUE(pixel(Vec3(0, -0.2f, 0)).isApprox(Vec2(32, 18), 1e-6f));  // world up is image up (y down)
  EXPECT_FALSE(c.project(Vec3(4, 0, 0)).has_value());                   // behind
  EXPECT_EQ(cap.frames[0].exposure, 1.0f);
  EXPECT_FALSE(cap.frames[0].exposureRecorded);
}

// The same cameras as transforms.json, COLMAP text and COLMAP binary: every known point projects to
// the same pixel through all four, and intrinsics come back exactly.
TEST(Colmap, ProjectionIsTheSameThroughEveryFormat) {
  const fs::path dir = freshDir("projection");
  const std::vector<Frame> frames = testFrames(dir / "images");
  writeTransforms(dir / "transforms.json", frames);
  writeColmap(dir / "text", dir / "images", frames, ColmapFormat::Text);
  writeColmap(dir / "binary", dir / "images", frames, ColmapFormat::Binary);
  const Capture json = readTransforms(dir / "transforms.json");
  const Capture text = readColmap(dir / "text", dir / "images");
  const Capture binary = readColmap(dir / "binary", dir / "images");
  ASSERT_EQ(text.frames.size(), frames.size());
  ASSERT_EQ(binary.frames.size(), frames.size());
  for (size_t i = 1; i < text.frames.size(); ++i) EXPECT_LT(text.frames[i - 1].image, text.frames[i].image);
  EXPECT_EQ(text.files, (std::vector<fs::path>{dir / "text" / "cameras.txt", dir / "text" / "images.txt"}));
  EXPECT_NE(readFile(dir / "text" / "cameras.txt").find("FULL_OPENCV"), std::string::npos);
  EXPECT_EQ(readFile(dir / "text" / "cameras.txt").find("\n5 "), std::string::npos) << "shared intrinsics, 4 cameras";
  size_t projected = 0;
  for (const Frame& original : frames) {
    SCOPED_TRACE(original.image.string());
    for (const Capture* cap : {&json, &text, &binary}) {
      const Camera& c = byImage(*cap, original.image).camera;
      expectSameIntrinsics(c, original.camera);
      EXPECT_LT((c.rotation - original.camera.rotation).cwiseAbs().maxCoeff(), 1e-6f);
      EXPECT_LT((c.position - original.camera.position).cwiseAbs().maxCoeff(), 1e-6f);
      for (const Vec3& p : knownPoints()) {
        const auto want = original.camera.project(p), got = c.project(p);
        ASSERT_TRUE(want && got) << p.transpose();
        EXPECT_LT((*want - *got).cwiseAbs().maxCoeff(), 1e-4f)
            << p.transpose() << ": " << want->transpose() << " vs " << got->transpose();
        projected += (want->array() >= 0).all() && want->x() <= 64 && want->y() <= 48;
      }
    }
  }
  EXPECT_GT(projected, 200u) << "most known points must land inside the images";
}

// Text and binary give the same Camera bit for bit; a transforms.json written from a COLMAP capture
// reads back bit for bit too (so the three forms of a capture are interchangeable).
TEST(Colmap, TextBinaryAndTransformsRoundTripBitIdentical) {
  const fs::path dir = freshDir("bits");
  const std::vector<Frame> frames = testFrames(dir / "images");
  writeColmap(dir / "text", dir / "images", frames, ColmapFormat::Text);
  writeColmap(dir / "binary", dir / "images", frames, ColmapFormat::Binary);
  const Capture text = readColmap(dir / "text", dir / "images");
  const Capture binary = readColmap(dir / "binary", dir / "images");
  ASSERT_EQ(text.frames.size(), binary.frames.size());
  for (size_t i = 0; i < text.frames.size(); ++i) expectIdentical(text.frames[i], binary.frames[i]);
  writeTransforms(dir / "transforms.json", text.frames);
  const Capture json = readTransforms(dir / "transforms.json");
  ASSERT_EQ(json.frames.size(), text.frames.size());
  for (size_t i = 0; i < json.frames.size(); ++i) expectIdentical(json.frames[i], text.frames[i]);
}

// A floor seen from above, prepared from transforms.json, COLMAP text and COLMAP binary: the
// frame cache, visibility index and initial albedo are byte-identical.
TEST(Colmap, PrepareOutputsAreIdenticalInEveryForm) {
  const fs::path dir = freshDir("prepare");
  const fs::path source = dir / "source";
  MeshData m;
  m.positions = {{-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}};  // normal +y
  m.faceObject = {0, 0};
  fs::create_directories(source / "images");
  writePly(source / "mesh.ply", m);
  std::vector<Frame> frames;
  for (int i = 0; i < 6; ++i) {
    Frame f;
    Camera& c = f.camera;
    c.width = 48, c.height = 32, c.fx = c.fy = 30, c.cx = 24, c.cy = 16;
    if (i % 2) c.distortion.k1 = -0.04f;
    c.position = Vec3(0.1f * (i % 3) - 0.1f, 2.0f, 0.1f * (i / 3) - 0.05f);
    c.rotation.col(0) = Vec3(1, 0, 0), c.rotation.col(1) = Vec3(0, 0, 1), c.rotation.col(2) = Vec3(0, -1, 0);
    c.rotation = c.rotation * Eigen::AngleAxisf(0.02f * i, Vec3(1, 2, 0.5f).normalized()).toRotationMatrix();
    Image img(c.width, c.height);
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        const Vec3 d = *c.rayDirection(Vec2(x + 0.5f, y + 0.5f));
        const Vec3 p = c.position + (-c.position.y() / d.y()) * d;
        img.set(x, y, Color(0.2f + 0.1f * std::sin(7 * p.x()), 0.3f, 0.2f + 0.1f * std::cos(5 * p.z())));
      }
    f.image = source / "images" / fmt::format("{:02d}.exr", i);
    writeExr(f.image, img);
    frames.push_back(f);
  }
  // Three capture folders holding the same mesh and images.
  const char* forms[] = {"json", "text", "binary"};
  for (const char* form : forms) fs::copy(source, dir / form, fs::copy_options::recursive);
  writeColmap(dir / "text" / "sparse" / "0", source / "images", frames, ColmapFormat::Text);
  writeColmap(dir / "binary" / "sparse" / "0", source / "images", frames, ColmapFormat::Binary);
  // transforms.json from the cameras COLMAP gives (a float rotation survives a quaternion only to ~1e-7).
  std::vector<Frame> fromColmap = readCapture(dir / "text").frames;
  for (Frame& f : fromColmap) f.image = dir / "json" / "images" / f.image.filename();
  writeTransforms(dir / "json" / "transforms.json", fromColmap);

  PrepareOptions o;
  o.resolutions = {128};
  o.atlas.gutterResolution = 128;
  o.tileTexels = 16;
  for (const char* form : forms) {
    const PrepareSummary s = prepareCapture(dir / form, dir / form / "work", o);
    EXPECT_EQ(s.frames, 6u) << form;
    EXPECT_EQ(s.keptFrames, 6u) << form;
  }
  for (const char* out : {"frames.bin", "visibility.bin", "albedo_init.exr"}) {
    const std::string json = readFile(dir / "json" / "work" / out);
    EXPECT_FALSE(json.empty()) << out;
    EXPECT_TRUE(json == readFile(dir / "text" / "work" / out)) << out << " differs: json vs COLMAP text";
    EXPECT_TRUE(json == readFile(dir / "binary" / "work" / out)) << out << " differs: json vs COLMAP binary";
  }
}

TEST(Colmap, CaptureFolderPrefersTransformsAndNamesWhatItLookedFor) {
  const fs::path dir = freshDir("folder");
  std::vector<Frame> frames = testFrames(dir / "images");
  writeColmap(dir / "sparse", dir / "images", frames, ColmapFormat::Binary);  // sparse/ without 0/
  EXPECT_EQ(readCapture(dir).frames.size(), 5u);
  EXPECT_EQ(readCapture(dir).file, dir / "sparse" / "images.bin");
  frames.resize(2);
  writeTransforms(dir / "transforms.json", frames);
  EXPECT_EQ(readCapture(dir).frames.size(), 2u) << "transforms.json wins";
  const fs::path empty = freshDir("empty");
  try {
    readCapture(empty);
    ADD_FAILURE() << "an empty folder was read";
  } catch (const Error& e) {
    const std::string msg = e.what();
    for (const char* part : {"transforms.json", "sparse/0", "cameras.txt", "images.bin"})
      EXPECT_NE(msg.find(part), std::string::npos) << msg;
    EXPECT_NE(msg.find(empty.string()), std::string::npos) << msg;
  }
}

// The size check on loading a frame names the COLMAP file that gave the camera, not transforms.json.
TEST(Colmap, ImageSizeMismatchNamesTheCamerasFile) {
  const fs::path dir = freshDir("size");
  fs::create_directories(dir / "images");
  writeExr(dir / "images" / "f.exr", Image(4, 2));
  writeFile(dir / "sparse" / "0" / "cameras.txt", "7 SIMPLE_PINHOLE 64 48 50 32 24\n");
  writeFile(dir / "sparse" / "0" / "images.txt", "3 1 0 0 0 0 0 0 7 f.exr\n");
  const Capture cap = readCapture(dir);
  try {
    loadFrameImage(cap.frames.at(0));
    ADD_FAILURE() << "size mismatch accepted";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(
        msg.find("image is 4x2 but " + (dir / "sparse" / "0" / "cameras.txt").string() + " (camera 7) says 64x48"),
        std::string::npos)
        << msg;
  }
}

TEST(Colmap, AllReadModelsMapOntoOpenCV) {
  const fs::path dir = freshDir("models");
  writeFile(dir / "images" / "a.png", "placeholder");
  const std::string image = "1 1 0 0 0 0 0 0 {} a.png\n\n";
  const std::vector<std::pair<std::string, Camera>> cases = [] {
    auto cam = [](float fx, float fy, Distortion d) {
      Camera c;
      c.width = 64, c.height = 48, c.fx = fx, c.fy = fy, c.cx = 32, c.cy = 24, c.distortion = d;
      return c;
    };
    return std::vector<std::pair<std::string, Camera>>{
        {"SIMPLE_PINHOLE 64 48 50 32 24", cam(50, 50, {})},
        {"PINHOLE 64 48 50 51 32 24", cam(50, 51, {})},
        {"SIMPLE_RADIAL 64 48 50 32 24 -0.1", cam(50, 50, {-0.1f, 0, 0, 0, 0})},
        {"RADIAL 64 48 50 32 24 -0.1 0.02", cam(50, 50, {-0.1f, 0.02f, 0, 0, 0})},
        {"OPENCV 64 48 50 51 32 24 -0.1 0.02 0.001 -0.002", cam(50, 51, {-0.1f, 0.02f, 0.001f, -0.002f, 0})},
        {"FULL_OPENCV 64 48 50 51 32 24 -0.1 0.02 0.001 -0.002 0.003 0 0 0",
         cam(50, 51, {-0.1f, 0.02f, 0.001f, -0.002f, 0.003f})},
    };
  }();
  for (size_t i = 0; i < cases.size(); ++i) {
    const fs::path model = dir / std::to_string(i);
    writeFile(model / "cameras.txt", "# comment\n\n  1 " + cases[i].first + "\r\n");
    writeFile(model / "images.txt", fmt::format(fmt::runtime(image), 1));
    SCOPED_TRACE(cases[i].first);
    expectSameIntrinsics(readColmap(model, dir / "images").frames.at(0).camera, cases[i].second);
  }
}

TEST(Colmap, CommentsBlankLinesAndPointsLinesAreSkipped) {
  const fs::path dir = freshDir("comments");
  for (const char* n : {"a b.png", "c.png"}) writeFile(dir / "images" / n, "placeholder");
  writeFile(dir / "cameras.txt", "# Camera list\n#   CAMERA_ID, MODEL\n\n2 PINHOLE 64 48 50 50 32 24\n\n");
  writeFile(dir / "images.txt",
            "# Image list\n\n"
            "5 1 0 0 0 0 0 0 2 c.png\r\n"
            "12.5 3.5 -1 40.1 7.25 17\r\n"
            "\n"
            "4 1.0004 0 0 0 0 0 1 2 a b.png\n"
            "\n");  // an empty points line
  const Capture cap = readColmap(dir, dir / "images");
  ASSERT_EQ(cap.frames.size(), 2u);
  EXPECT_EQ(cap.frames[0].image, dir / "images" / "a b.png");  // sorted by NAME, spaces kept
  EXPECT_EQ(cap.frames[1].image, dir / "images" / "c.png");
  EXPECT_TRUE(cap.frames[0].camera.rotation.isApprox(Mat3::Identity()));  // normalised from |q| = 1.0004
  EXPECT_TRUE(cap.frames[0].camera.position.isApprox(Vec3(0, 0, -1)));
}

namespace {

// A valid model (two images of one PINHOLE camera) in text, with one line replaced.
struct TextModel {
  std::string cameras = "1 PINHOLE 64 48 50 50 32 24\n";
  std::string images = "1 1 0 0 0 0 0 5 1 a.exr\n\n2 1 0 0 0 0 0 6 1 b.exr\n\n";
};

// The error reading `model`, "" if it reads.
std::string errorReading(const fs::path& model, const fs::path& images) {
  try {
    readColmap(model, images);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

void expectError(const fs::path& model, const fs::path& images, const std::string& file, const std::string& what) {
  const std::string err = errorReading(model, images);
  EXPECT_NE(err.find(what), std::string::npos) << "expected '" << what << "' in: " << err;
  EXPECT_NE(err.find((model / file).string()), std::string::npos) << "must name " << file << ": " << err;
  EXPECT_EQ(err.find('\n'), std::string::npos) << err;
}

// Little-endian bytes of a value.
template <typename T>
std::string le(T v) {
  std::string s(sizeof(T), '\0');
  std::memcpy(s.data(), &v, sizeof(T));
  return s;
}

}  // namespace

TEST(Colmap, BadTextGivesOneLineErrorsNamingFileAndField) {
  const fs::path dir = freshDir("bad_text");
  for (const char* n : {"a.exr", "b.exr"}) writeFile(dir / "images" / n, "placeholder");
  struct Case {
    std::string cameras, images, file, what;
  };
  const TextModel ok;
  const std::vector<Case> cases = {
      {"1 OPENCV_FISHEYE 64 48 50 50 32 24 0 0 0 0\n", ok.images, "cameras.txt",
       "camera 1 (OPENCV_FISHEYE): camera model OPENCV_FISHEYE is not supported"},
      {"1 PINHOLE 64 48 50 50 32\n", ok.images, "cameras.txt", "camera 1 (PINHOLE): 3 parameters, PINHOLE takes 4"},
      {"1 PINHOLE 64.5 48 50 50 32 24\n", ok.images, "cameras.txt", "WIDTH '64.5' is not an integer"},
      {"1 PINHOLE 64 48\n", ok.images, "cameras.txt", "0 parameters, PINHOLE takes 4 (fx fy cx cy)"},
      {"1 PINHOLE 64 0 50 50 32 24\n", ok.images, "cameras.txt", "bad image size 64x0"},
      {"1 PINHOLE 64 48 0 50 32 24\n", ok.images, "cameras.txt", "'fx' is 0, must be in (0, 1e+07) pixels"},
      {"1 SIMPLE_PINHOLE 64 48 1e39 32 24\n", ok.images, "cameras.txt",
       "parameter 'f' is 1e+39, not a finite number (in float)"},
      {"1 PINHOLE 64 48 50 50 32 nan\n", ok.images, "cameras.txt", "parameter 'cy' is nan"},
      {"1 PINHOLE 64 48 50 50 32 1e9\n", ok.images, "cameras.txt", "'cy' is 1000000000, must be in [-456, 504]"},
      {"1 PINHOLE 64 48 50 50 32 x\n", ok.images, "cameras.txt", "parameter 'x' is not a number"},
      {"1 FULL_OPENCV 64 48 50 50 32 24 0 0 0 0 0 0.1 0 0\n", ok.images, "cameras.txt",
       "parameter 'k4' is 0.1; relume reads FULL_OPENCV only with k4 = k5 = k6 = 0"},
      {ok.cameras + "1 PINHOLE 64 48 50 50 32 24\n", ok.images, "cameras.txt",
       "line 2: camera 1 (PINHOLE): CAMERA_ID 1 appears twice"},
      {"-1 PINHOLE 64 48 50 50 32 24\n", ok.images, "cameras.txt", "CAMERA_ID '-1' is not an integer"},
      {"1 PINHOLE\n", ok.images, "cameras.txt", "line 1: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]"},
      {ok.cameras, "1 1 0 0 0 0 0 5 2 a.exr\n\n", "images.txt", "image 1 'a.exr': CAMERA_ID 2 is not in"},
      {ok.cameras, "1 1 0 0 0 0 0 5 1 missing.exr\n\n", "images.txt",
       "image 1 'missing.exr': image file " + (dir / "images" / "missing.exr").string() + " not found"},
      {ok.cameras, "1 nan 0 0 0 0 0 5 1 a.exr\n\n", "images.txt", "quaternion QW QX QY QZ (nan 0 0 0) is not finite"},
      {ok.cameras, "1 1 0 0 inf 0 0 5 1 a.exr\n\n", "images.txt", "quaternion QW QX QY QZ (1 0 0 inf) is not finite"},
      {ok.cameras, "1 0.9 0 0 0 0 0 5 1 a.exr\n\n", "images.txt", "quaternion QW QX QY QZ has norm 0.9, must be 1"},
      {ok.cameras, "1 1 0 0 0 0 0 nan 1 a.exr\n\n", "images.txt", "translation TX TY TZ (0 0 nan) is not finite"},
      {ok.cameras, "1 1 0 0 0 0 0 2e6 1 a.exr\n\n", "images.txt",
       "camera position -R^T t [2] is -2000000, must be within +-1e+06 m"},
      {ok.cameras, "1 1 0 0 0 0 0 5 1 a.exr\n\n1 1 0 0 0 0 0 6 1 b.exr\n\n", "images.txt", "IMAGE_ID 1 appears twice"},
      {ok.cameras, "1 1 0 0 0 0 0 5 1 a.exr\n\n2 1 0 0 0 0 0 6 1 a.exr\n\n", "images.txt",
       "NAME 'a.exr' appears twice"},
      {ok.cameras, "1 1 0 0 0 0 0 5 1\n\n", "images.txt",
       "line 1: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"},
      {ok.cameras, "1 1 zero 0 0 0 0 5 1 a.exr\n\n", "images.txt", "image 1 'a.exr': QX 'zero' is not a number"},
      {ok.cameras, "1 1 0 0 0 0 0 5 99999999999 a.exr\n\n", "images.txt", "CAMERA_ID '99999999999' is not an integer"},
      {ok.cameras, "1 1 0 0 0 0 0 5 1 /etc/passwd\n\n", "images.txt", "NAME must be a path relative to"},
      {ok.cameras, "# nothing\n", "images.txt", "no images"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(fmt::format("case {}: {}", i, cases[i].what));
    const fs::path model = dir / fmt::format("m{}", i);
    writeFile(model / "cameras.txt", cases[i].cameras);
    writeFile(model / "images.txt", cases[i].images);
    expectError(model, dir / "images", cases[i].file, cases[i].what);
  }
  writeFile(dir / "ok" / "cameras.txt", ok.cameras);
  writeFile(dir / "ok" / "images.txt", ok.images);
  EXPECT_EQ(errorReading(dir / "ok", dir / "images"), "");
  EXPECT_NE(errorReading(dir / "none", dir / "images").find("no COLMAP model"), std::string::npos);
}

TEST(Colmap, BadBinaryGivesOneLineErrorsNamingFileAndField) {
  const fs::path dir = freshDir("bad_binary");
  for (const char* n : {"a.exr", "b.exr"}) writeFile(dir / "images" / n, "placeholder");
  // cameras.bin with one PINHOLE camera: 8 count, 4 id, 4 model, 8 width, 8 height, 4 x 8 params.
  const std::string camera = le<uint32_t>(1) + le<int32_t>(1) + le<uint64_t>(64) + le<uint64_t>(48) + le(50.0) +
                             le(50.0) + le(32.0) + le(24.0);
  const std::string cameras = le<uint64_t>(1) + camera;
  auto image = [](uint32_t id, uint32_t cameraId, const std::string& name, const std::string& points) {
    return le(id) + le(1.0) + le(0.0) + le(0.0) + le(0.0) + le(0.0) + le(0.0) + le(5.0) + le(cameraId) + name +
           std::string(1, '\0') + points;
  };
  const std::string noPoints = le<uint64_t>(0);
  const std::string onePoint = le<uint64_t>(1) + le(1.5) + le(2.5) + le<int64_t>(-1);
  const std::string images = le<uint64_t>(2) + image(1, 1, "a.exr", onePoint) + image(2, 1, "b.exr", noPoints);
  struct Case {
    std::string cameras, images, file, what;
  };
  std::string otherModel = cameras;
  otherModel[12] = 5;  // MODEL_ID: OPENCV_FISHEYE
  std::string unknownModel = cameras;
  unknownModel[12] = 99;
  const std::vector<Case> cases = {
      {cameras.substr(0, cameras.size() - 4), images, "cameras.bin",
       "camera 1 (PINHOLE): truncated at byte 56 reading cy"},
      {cameras.substr(0, 5), images, "cameras.bin", "truncated at byte 0 reading num_cameras"},
      {le<uint64_t>(1000000) + camera, images, "cameras.bin", "num_cameras is 1000000 but only 56 bytes follow"},
      {le<uint64_t>(~0ull) + camera, images, "cameras.bin", "num_cameras is 18446744073709551615 but only"},
      {cameras + "x", images, "cameras.bin", "1 bytes after the last camera"},
      {otherModel, images, "cameras.bin", "camera 1 (OPENCV_FISHEYE): camera model OPENCV_FISHEYE is not supported"},
      {unknownModel, images, "cameras.bin", "camera 1 (MODEL_ID 99): camera model MODEL_ID 99 is not supported"},
      {cameras, le<uint64_t>(3) + images.substr(8), "images.bin", "num_reg_images is 3 but only 180 bytes follow"},
      {cameras, le<uint64_t>(2) + images.substr(8, images.size() - 9), "images.bin",
       "image 2 'b.exr': truncated at byte 180 reading num_points2D"},
      {cameras, le<uint64_t>(1) + image(1, 1, "a.exr", le<uint64_t>(1ull << 40)), "images.bin",
       "image 1 'a.exr': num_points2D is 1099511627776 but only 0 bytes follow (at least 24 each)"},
      {cameras, le<uint64_t>(1) + image(1, 1, "a.exr", onePoint) + "junk", "images.bin",
       "4 bytes after the last image"},
      {cameras, le<uint64_t>(1) + le<uint32_t>(1) + std::string(60, '\0') + "no_null_at_the_end.exr", "images.bin",
       "truncated at byte 72 reading NAME (no terminating null)"},
      {cameras, le<uint64_t>(1ull << 60) + images.substr(8), "images.bin", "num_reg_images is 1152921504606846976"},
      {cameras, le<uint64_t>(1) + image(1, 3, "a.exr", noPoints), "images.bin", "CAMERA_ID 3 is not in"},
      {cameras, le<uint64_t>(2) + image(1, 1, "a.exr", noPoints) + image(1, 1, "b.exr", noPoints), "images.bin",
       "IMAGE_ID 1 appears twice"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(fmt::format("case {}: {}", i, cases[i].what));
    const fs::path model = dir / fmt::format("m{}", i);
    writeFile(model / "cameras.bin", cases[i].cameras);
    writeFile(model / "images.bin", cases[i].images);
    expectError(model, dir / "images", cases[i].file, cases[i].what);
  }
  writeFile(dir / "ok" / "cameras.bin", cameras);
  writeFile(dir / "ok" / "images.bin", images);
  EXPECT_EQ(errorReading(dir / "ok", dir / "images"), "");
}
