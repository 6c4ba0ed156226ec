#include <gtest/gtest.h>

#include <fstream>

#include "capture/frame_image.h"
#include "capture/transforms.h"
#include "core/error.h"
#include "io/json.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {
fs::path writeFile(const std::string& name, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / "relume_capture_test";
  fs::create_directories(dir);
  std::ofstream(dir / name) << text;
  return dir / name;
}
std::string errorOf(const fs::path& p) {
  try {
    readTransforms(p);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Transforms, OpenGLToOpenCVHandComputed) {
  // Camera at (1,2,3) rotated 90 degrees about +y (OpenGL: looks along -z, so after the rotation
  // it looks along -x). In OpenCV axes the forward (z) axis must be world -x, down (y) world -y,
  // right (x) world -z... worked out: R_gl columns = (0,0,-1), (0,1,0), (1,0,0).
  const fs::path p = writeFile("t1.json", R"({"fl_x": 100, "fl_y": 110, "cx": 50, "cy": 40, "w": 100, "h": 80,
    "frames": [{"file_path": "a.exr", "transform_matrix": [[0,0,1,1],[0,1,0,2],[-1,0,0,3],[0,0,0,1]]}]})");
  const Capture cap = readTransforms(p);
  ASSERT_EQ(cap.frames.size(), 1u);
  const Camera& c = cap.frames[0].camera;
  EXPECT_TRUE(c.position.isApprox(Vec3(1, 2, 3)));
  EXPECT_TRUE(c.rotation.col(0).isApprox(Vec3(0, 0, -1)));  // right
  EXPECT_TRUE(c.rotation.col(1).isApprox(Vec3(0, -1, 0)));  // down
  EXPECT_TRUE(c.rotation.col(2).isApprox(Vec3(-1, 0, 0)));  // forward
  // A point straight ahead projects to the principal point; one above projects above it.
  EXPECT_TRUE(c.project(Vec3(-4, 2, 3))->isApprox(Vec2(50, 40)));
  EXPECT_LT(c.project(Vec3(-4, 3, 3))->y(), 40);
  EXPECT_EQ(cap.frames[0].image, p.parent_path() / "a.exr");
  EXPECT_FLOAT_EQ(c.fy, 110);
}

TEST(Transforms, RoundTripThroughWriter) {
  Frame f;
  f.camera.width = 64, f.camera.height = 48, f.camera.fx = f.camera.fy = 50, f.camera.cx = 32, f.camera.cy = 24;
  f.camera.distortion.k1 = -0.1f;
  f.camera.rotation = Eigen::AngleAxisf(0.7f, Vec3(1, 1, 0).normalized()).toRotationMatrix();
  f.camera.position = Vec3(0.5f, -1, 2);
  const fs::path dir = fs::temp_directory_path() / "relume_capture_test";
  f.image = dir / "images" / "x.exr";
  f.exposure = 2.0f;
  writeTransforms(dir / "rt.json", {f});
  const Capture cap = readTransforms(dir / "rt.json");
  EXPECT_TRUE(cap.frames[0].camera.rotation.isApprox(f.camera.rotation, 1e-5f));
  EXPECT_TRUE(cap.frames[0].camera.position.isApprox(f.camera.position));
  EXPECT_FLOAT_EQ(cap.frames[0].camera.distortion.k1, -0.1f);
  EXPECT_FLOAT_EQ(cap.frames[0].exposure, 2.0f);
  EXPECT_EQ(cap.frames[0].image, f.image);
  EXPECT_TRUE(cap.frames[0].camera.filter.isUnitBox());  // relume's own renders
  EXPECT_FALSE(cap.exactPoses);  // a pose is an estimate unless the capture says otherwise
  writeTransforms(dir / "rt_exact.json", {f}, true);
  EXPECT_TRUE(readTransforms(dir / "rt_exact.json").exactPoses);
  // A capture's pixel filter, common and per frame, survives the writer.
  Frame g = f;
  f.camera.filter = PixelFilter(PixelFilterType::BlackmanHarris, 1.5f);
  g.camera.filter = PixelFilter(PixelFilterType::Gaussian, 2.0f);
  writeTransforms(dir / "rt_filter.json", {f, f, g});
  const Capture filtered = readTransforms(dir / "rt_filter.json");
  EXPECT_EQ(filtered.frames[1].camera.filter, f.camera.filter);
  EXPECT_EQ(filtered.frames[2].camera.filter, g.camera.filter);
  // Clip levels survive it; the defaults (none) are not written.
  g.clipLow = 0.01f, g.clipHigh = 3.5f;
  writeTransforms(dir / "rt_clip.json", {f, g});
  const Capture clipped = readTransforms(dir / "rt_clip.json");
  EXPECT_FLOAT_EQ(clipped.frames[1].clipLow, 0.01f);
  EXPECT_FLOAT_EQ(clipped.frames[1].clipHigh, 3.5f);
  EXPECT_EQ(clipped.frames[0].clipLow, Frame{}.clipLow);
  EXPECT_EQ(clipped.frames[0].clipHigh, Frame{}.clipHigh);
  EXPECT_EQ(readJson(dir / "rt_clip.json")["frames"][0].count("clip_high"), 0u);
}

TEST(Transforms, ExactPosesIsABoolean) {
  const std::string frames = R"("fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a.exr",
    "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}])";
  EXPECT_FALSE(readTransforms(writeFile("exact_false.json", "{\"exact_poses\": false, " + frames + "}")).exactPoses);
  try {
    readTransforms(writeFile("exact_bad.json", "{\"exact_poses\": 1, " + frames + "}"));
    FAIL() << "a number taken for exact_poses";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("exact_poses"), std::string::npos) << e.what();
  }
}

// An albedo pass (eval's per-pixel reference) is a path relative to the json, kept by writeTransforms.
TEST(Transforms, AlbedoPathIsRelativeToTheJsonAndWrittenBack) {
  const fs::path p = writeFile("albedo.json", R"({"fl_x": 10, "w": 10, "h": 10, "frames": [
    {"file_path": "test/a.exr", "albedo_path": "test/a_albedo.exr",
     "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
    {"file_path": "test/b.exr", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})");
  const Capture cap = readTransforms(p);
  EXPECT_EQ(cap.frames[0].albedo, p.parent_path() / "test/a_albedo.exr");
  EXPECT_TRUE(cap.frames[1].albedo.empty());
  const fs::path again = p.parent_path() / "albedo_again.json";
  writeTransforms(again, cap.frames);
  const Capture back = readTransforms(again);
  EXPECT_EQ(back.frames[0].albedo, cap.frames[0].albedo);
  EXPECT_TRUE(back.frames[1].albedo.empty());
  EXPECT_NE(errorOf(writeFile("albedo_bad.json", R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a.exr",
    "albedo_path": 3, "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})")).find("albedo_path"),
            std::string::npos);
}

TEST(Transforms, PixelFilterDefaultsToCyclesWidth) {
  const std::string frame = R"("file_path": "a.exr", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]])";
  const Capture cap = readTransforms(
      writeFile("filter.json", R"({"fl_x": 10, "w": 10, "h": 10, "pixel_filter": {"type": "blackman-harris"},
    "frames": [{)" + frame + R"(}, {"pixel_filter": {"type": "box"}, )" +
                                   frame + "}]}"));
  EXPECT_EQ(cap.frames[0].camera.filter, PixelFilter(PixelFilterType::BlackmanHarris, 1.5f));
  EXPECT_TRUE(cap.frames[1].camera.filter.isUnitBox());
}

TEST(Transforms, MalformedInputsGiveOneLineErrors) {
  const std::string frame = R"("file_path": "a.exr", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]])";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{not json", "malformed JSON"},
      {R"({"fl_x": 1, "w": 2, "h": 2})", "missing 'frames'"},
      {R"({"frames": []})", "no frames"},
      {R"({"w": 10, "h": 10, "frames": [{)" + frame + "}]}", "missing 'fl_x'"},
      {R"({"fl_x": "ten", "w": 10, "h": 10, "frames": [{)" + frame + "}]}", "'fl_x' must be a finite number"},
      {R"({"fl_x": 10, "w": -1, "h": 10, "frames": [{)" + frame + "}]}", "bad image size"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "camera_model": "FISHEYE", "frames": [{)" + frame + "}]}",
       "unsupported camera_model"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0]]}]})",
       "must be a 4x4"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a", "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0]]}]})",
       "not orthonormal"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}]})",
       "missing 'file_path'"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "exposure": 0, "frames": [{)" + frame + "}]}", "'exposure' is 0, must be in [1e-08, 1e+08]"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "camera_model": 3, "frames": [{)" + frame + "}]}",
       "'camera_model' must be a string"},
      // Finite as a double, infinite as a float: Embree used to abort on the rays.
      {R"({"fl_x": 1e39, "w": 10, "h": 10, "frames": [{)" + frame + "}]}",
       "field 'fl_x' must be a finite number (in float)"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"cx": 1e300, )" + frame + "}]}",
       "frame 0: field 'cx' must be a finite number (in float)"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"k1": 1e39, )" + frame + "}]}",
       "frame 0: field 'k1' must be a finite number (in float)"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"cx": 1e30, )" + frame + "}]}",
       "frame 0: 'cx' is 1e+30, must be in [-95, 105]"},
      {R"({"fl_x": 10, "w": 10, "h": 20, "frames": [{"cy": -201, )" + frame + "}]}",
       "frame 0: 'cy' is -201, must be in [-190, 210]"},
      {R"({"fl_x": 1e7, "w": 10, "h": 10, "frames": [{)" + frame + "}]}",
       "frame 0: 'fl_x' is 10000000, must be in (0, 1e+07) pixels"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"fl_y": 0, )" + frame + "}]}",
       "frame 0: 'fl_y' is 0, must be in (0, 1e+07) pixels"},
      {R"({"fl_x": 10, "w": 1e300, "h": 10, "frames": [{)" + frame + "}]}",
       "field 'w' must be a finite number (in float)"},
      {R"({"fl_x": 10, "w": 1e30, "h": 10, "frames": [{)" + frame + "}]}", "frame 0: bad image size 1e+30x10"},
      {R"({"fl_x": 10, "w": 10.5, "h": 10, "frames": [{)" + frame + "}]}", "frame 0: bad image size 10.5x10"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0,1e19],[0,1,0,0],[0,0,1,0]]}]})",
       "frame 0: transform_matrix[0][3] (position) is 1e+19, must be within +-1e+06 m"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,-1e6]]}]})",
       "frame 0: transform_matrix[2][3] (position) is -1000000, must be within +-1e+06 m"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"file_path": "a", "transform_matrix": [[1,0.5,0,0],[0,1,0,0],[0,0,1,0]]}]})",
       "frame 0: transform_matrix rotation is not orthonormal (det 1, |R^T R - I| 0.5"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "pixel_filter": "box", "frames": [{)" + frame + "}]}",
       "'pixel_filter' must be an object with a string 'type'"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "pixel_filter": {"type": "mitchell"}, "frames": [{)" + frame + "}]}",
       "pixel filter 'mitchell': must be box, gaussian or blackman-harris"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "frames": [{"pixel_filter": {"type": "box", "width": 0}, )" + frame + "}]}",
       "frame 0: pixel filter width 0: must be in (0, 16] pixels"},
      {R"({"fl_x": 10, "w": 10, "h": 10, "pixel_filter": {"type": "box", "size": 2}, "frames": [{)" + frame + "}]}",
       "unknown key 'pixel_filter.size'"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const fs::path p = writeFile("bad" + std::to_string(i) + ".json", cases[i].first);
    const std::string err = errorOf(p);
    EXPECT_NE(err.find(cases[i].second), std::string::npos) << "case " << i << ": " << err;
    EXPECT_NE(err.find(p.string()), std::string::npos) << "error must name the file: " << err;
    EXPECT_EQ(err.find('\n'), std::string::npos);
  }
  EXPECT_NE(errorOf("/nonexistent/transforms.json").find("not found"), std::string::npos);
}

TEST(Transforms, NanPixelsAreMaskedAndCounted) {
  const fs::path dir = fs::temp_directory_path() / "relume_capture_test";
  Image img(4, 2);
  img.set(1, 1, Color(NAN, 1, 1));
  img.set(2, 0, Color(INFINITY, 0, 0));
  img.set(0, 0, Color(2, 4, 6));
  writeExr(dir / "nan.exr", img);
  Frame f;
  f.camera.width = 4, f.camera.height = 2;
  f.image = dir / "nan.exr";
  f.exposure = 2.0f;
  const FrameImage frame = loadFrame(f);
  const Image& loaded = frame.image;
  EXPECT_EQ(frame.read.nonFinitePixels, 2u);
  EXPECT_EQ(loaded.at(1, 1)[0], kMaskedPixel);
  EXPECT_EQ(loaded.at(2, 0)[1], kMaskedPixel);
  EXPECT_TRUE(loaded.at(0, 0).isApprox(Color(1, 2, 3)));  // divided by the exposure
  f.camera.width = 5;
  EXPECT_THROW(loadFrameImage(f), Error);
}

#include "capture/objects.h"

TEST(ObjectNames, BothFormsAndErrors) {
  const fs::path a = writeFile("objects_a.json", R"({"objects": [{"id": 2, "name": "sofa"}]})");
  EXPECT_EQ(readObjectNames(a).at(2), "sofa");
  const fs::path b = writeFile("objects_b.json", R"({"0": "floor", "7": "lamp"})");
  EXPECT_EQ(readObjectNames(b).at(7), "lamp");
  for (const char* bad : {R"({"x": "floor"})", R"({"objects": [{"id": -1, "name": "a"}]})", R"({"1": 3})", "[1,2]",
                          R"({"objects": [{"id": 4294967296, "name": "wraps to 0"}]})", R"({"4294967296": "floor"})"}) {
    const fs::path p = writeFile("objects_bad.json", bad);
    try {
      readObjectNames(p);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos);
    }
  }
}
