// Every reader rejects hostile input with a one-line error naming the file; valid variants load.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "core/error.h"
#include "io/image.h"
#include "io/json.h"
#include "io/mesh_data.h"
#include "scene/appearance.h"
#include "scene/mesh.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {
fs::path tmpDir() {
  const fs::path d = fs::temp_directory_path() / "relume_io_test";
  fs::create_directories(d);
  return d;
}
fs::path writeBytes(const std::string& name, const std::string& bytes) {
  const fs::path p = tmpDir() / name;
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}
template <typename F>
std::string errorOf(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "<no error>";
}
const std::string kAsciiHeader =
    "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nproperty int segment_id\nend_header\n";
const std::string kAsciiBody = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 7\n";

std::string binaryPly(bool bigEndian, int faceIndex = 2, uint32_t declaredFaces = 1) {
  std::string s = std::string("ply\nformat ") + (bigEndian ? "binary_big_endian" : "binary_little_endian") +
                  " 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float "
                  "u\nproperty float v\n"
                  "element face " +
                  std::to_string(declaredFaces) +
                  "\nproperty list uchar uint vertex_indices\nproperty uchar object_id\nend_header\n";
  auto put = [&](auto v) {
    char b[sizeof(v)];
    std::memcpy(b, &v, sizeof(v));
    if (bigEndian) std::reverse(b, b + sizeof(v));
    s.append(b, sizeof(v));
  };
  const float verts[3][5] = {{0, 0, 0, 0, 0}, {1, 0, 0, 1, 0}, {0, 1, 0, 0, 1}};
  for (auto& v : verts)
    for (float x : v) put(x);
  put(uint8_t{3});
  put(uint32_t{0}), put(uint32_t{1}), put(static_cast<uint32_t>(faceIndex));
  put(uint8_t{5});
  return s;
}
}  // namespace

TEST(Ply, AsciiPolygonsAreFanTriangulatedWithLabels) {
  const MeshData m = readPly(writeBytes("quad.ply", kAsciiHeader + kAsciiBody));
  ASSERT_EQ(m.triangles.size(), 2u);
  EXPECT_EQ(m.faceObject, (std::vector<int32_t>{7, 7}));
  EXPECT_EQ(m.polygonsTriangulated, 1u);
}

TEST(Ply, BinaryBothEndiannessWithUv) {
  for (bool be : {false, true}) {
    const MeshData m = readPly(writeBytes(be ? "be.ply" : "le.ply", binaryPly(be)));
    ASSERT_EQ(m.triangles.size(), 1u);
    EXPECT_TRUE(m.positions[1].isApprox(Vec3(1, 0, 0)));
    ASSERT_EQ(m.uvs.size(), 3u);
    EXPECT_TRUE(m.uvs[2].isApprox(Vec2(0, 1)));
    EXPECT_EQ(m.faceObject[0], 5);
  }
}

TEST(Ply, WriterRoundTrip) {
  MeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.uvs = {{0, 0}, {1, 0}, {0, 1}};
  m.triangles = {{0, 1, 2}};
  m.faceObject = {3};
  writePly(tmpDir() / "rt.ply", m);
  const MeshData r = readPly(tmpDir() / "rt.ply");
  EXPECT_EQ(r.triangles, m.triangles);
  EXPECT_EQ(r.faceObject, m.faceObject);
  EXPECT_TRUE(r.uvs[1].isApprox(m.uvs[1]));
}

TEST(Ply, MalformedFilesGiveOneLineErrors) {
  const std::string good = binaryPly(false);
  const std::vector<std::tuple<std::string, std::string, std::string>> cases = {
      {"empty.ply", "", "not a PLY"},
      {"noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n", "no 'end_header'"},
      {"truncated.ply", good.substr(0, good.size() - 7), "truncated"},
      {"wrongcount.ply", binaryPly(false, 2, 3), "truncated binary data while reading face"},
      {"huge.ply",
       "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty "
       "float z\nend_header\n",
       "declares 4000000000"},
      {"oob.ply", binaryPly(false, 9), "out of range"},
      {"negidx.ply", kAsciiHeader + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 -1 2 0\n", "out of range"},
      {"token.ply", kAsciiHeader + "0 0 0\n1 zero 0\n1 1 0\n0 1 0\n3 0 1 2 0\n", "non-numeric token 'zero'"},
      {"badtype.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quaternion x\nend_header\n0\n",
       "unknown property type"},
      {"badformat.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown PLY format"},
      {"noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n0\n", "lacks x/y/z"},
      {"noface.ply",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 "
       "0\n",
       "no faces"},
      {"badlabel.ply", kAsciiHeader + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 -4\n", "not a non-negative integer"},
      {"hugelist.ply", kAsciiHeader + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n200 0 1 2\n", "unexpected end of file"},
      {"noprops.ply", "ply\nformat ascii 1.0\nelement junk 18446744073709551615\n" + kAsciiHeader.substr(21),
       "element 'junk' declares 18446744073709551615 entries but no properties"},
      {"nanlist.ply", kAsciiHeader + "0 0 0\n1 0 0\n1 1 0\n0 1 0\nnan 0 1 2 0\n", "face 0: bad list length nan"},
      {"nanvertlist.ply",
       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty list "
       "float int extra\nend_header\n0 0 0 nan\n",
       "vertex 0: bad list length nan"},
      {"nanjunklist.ply",
       "ply\nformat ascii 1.0\nelement junk 1\nproperty list float int extra\n" + kAsciiHeader.substr(21) + "nan\n",
       "element 'junk' 0: bad list length nan"},
      {"fraclist.ply", kAsciiHeader + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3.5 0 1 2 0\n", "face 0: bad list length 3.5"},
      {"nanvert.ply", kAsciiHeader + "0 0 nan\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 0\n", "non-finite position"},
  };
  for (const auto& [name, bytes, expected] : cases) {
    const fs::path p = writeBytes(name, bytes);
    const std::string err = errorOf([&] { readPly(p); });
    EXPECT_NE(err.find(expected), std::string::npos) << name << ": " << err;
    EXPECT_NE(err.find(p.string()), std::string::npos) << name << ": " << err;
    EXPECT_EQ(err.find('\n'), std::string::npos) << name;
  }
  EXPECT_NE(errorOf([] { readPly("/nonexistent.ply"); }).find("not found"), std::string::npos);
}

TEST(Ply, FuzzedTruncationsNeverCrash) {
  const std::string good = binaryPly(false);
  const std::string ascii = kAsciiHeader + kAsciiBody;
  for (const std::string* src : {&good, &ascii})
    for (size_t n = 0; n < src->size(); ++n) {
      const fs::path p = writeBytes("cut.ply", src->substr(0, n));
      try {
        readPly(p);
      } catch (const Error&) {
      }
    }
  SUCCEED();
}

TEST(Obj, GroupsBecomeSegmentsAndErrorsAreClear) {
  const fs::path ok = writeBytes("a.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\no first\nf 1 2 3\no second\nf 1 3 4\n");
  const MeshData m = readMesh(ok);
  ASSERT_EQ(m.triangles.size(), 2u);
  EXPECT_NE(m.faceObject[0], m.faceObject[1]);
  EXPECT_EQ(m.objectNames[m.faceObject[1]], "second");
  const fs::path bad = writeBytes("b.obj", "v 0 0 0\nv 1 0 0\nf 1 2 9\n");
  const std::string err = errorOf([&] { readMesh(bad); });
  EXPECT_NE(err.find(bad.string()), std::string::npos) << err;
  EXPECT_NE(errorOf([] { readMesh("x.stl"); }).find("unsupported mesh format"), std::string::npos);
}

TEST(Mesh, DegenerateTrianglesAreDroppedAndCounted) {
  MeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}};
  m.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 0, 2}};  // second is collinear, third repeats a vertex
  const TriangleMesh t = buildMesh(m, "test");
  EXPECT_EQ(t.triangles.size(), 1u);
  EXPECT_EQ(t.droppedDegenerate, 2u);
  m.triangles = {{0, 1, 3}};
  EXPECT_NE(errorOf([&] { buildMesh(m, "all-bad"); }).find("every triangle is degenerate"), std::string::npos);
}

TEST(Images, MissingAndCorruptImagesGiveErrors) {
  EXPECT_NE(errorOf([] { readImage("/nonexistent.exr"); }).find("not found"), std::string::npos);
  const fs::path junk = writeBytes("junk.exr", "this is not an exr");
  const std::string err = errorOf([&] { readImage(junk); });
  EXPECT_NE(err.find(junk.string()), std::string::npos) << err;
}

TEST(Images, PngIsSrgbDecodedExrIsLinear) {
  Image img(2, 1);
  img.set(0, 0, Color::Constant(0.5f));
  img.set(1, 0, Color::Constant(0.2f));
  writeExr(tmpDir() / "lin.exr", img);
  writePng(tmpDir() / "srgb.png", img);
  EXPECT_FLOAT_EQ(readImage(tmpDir() / "lin.exr").at(0, 0)[0], 0.5f);
  EXPECT_NEAR(readImage(tmpDir() / "srgb.png").at(1, 0)[0], 0.2f, 0.004f);  // 8-bit quantisation
}

// Equal pixels are equal bytes whenever they are written: resume, the prepare cache and the
// form-equivalence tests compare files. (OIIO's default stamps each EXR with the second it was written.)
TEST(Images, EqualPixelsWrittenASecondApartAreEqualBytes) {
  Image img(2, 1);
  img.set(0, 0, Color(0.1f, 0.2f, 0.3f));
  const auto bytes = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  writeExr(tmpDir() / "first.exr", img);
  writePng(tmpDir() / "first.png", img);
  std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  writeExr(tmpDir() / "second.exr", img);
  writePng(tmpDir() / "second.png", img);
  EXPECT_EQ(bytes(tmpDir() / "first.exr"), bytes(tmpDir() / "second.exr"));
  EXPECT_EQ(bytes(tmpDir() / "first.png"), bytes(tmpDir() / "second.png"));
}

TEST(SceneFile, RejectsBadFields) {
  MeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  writePly(tmpDir() / "scene_mesh.ply", m);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"objects": []})", "missing 'mesh'"},
      {R"({"mesh": "scene_mesh.ply", "model": "oren"})", "'model' must be principled-v1 or gltf, not 'oren'"},
      {R"({"mesh": "scene_mesh.ply", "diffuse": "disney"})", "'diffuse' is no longer read"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 4}]})", "id 4 not in the mesh"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "roughness": "rough"}]})", "'roughness' must be a number"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "emission": [1, 2]}]})", "[r,g,b]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "emission": [-1, 0, 0]}]})",
       "objects[0]: 'emission[0]' is -1, must be in [0, 1e8] (the radiance bound)"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "emission": 1e39}]})",
       "objects[0]: 'emission' is 1e+39, must be in [0, 1e8] (the radiance bound)"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "emission": [0, 1e300, 0]}]})",
       "'emission[1]' is 1e+300, must be in [0, 1e8] (the radiance bound)"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "albedo": 1.5}]})", "'albedo' is 1.5, must be in [0, 1]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "albedo": [0.5, 0.5, -0.1]}]})",
       "'albedo[2]' is -0.1, must be in [0, 1]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "roughness": 0.01}]})",
       "'roughness' is 0.01, must be in [0.035, 1]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "roughness": 1e39}]})",
       "'roughness' is 1e+39, must be in [0.035, 1]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "specular": 1.01}]})",
       "'specular' is 1.01, must be in [0, 1]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "specular": -0.5}]})",
       "'specular' is -0.5, must be in [0, 1]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 4294967296}]})",
       "objects[0]: 'id' is 4294967296, must be in [0, 2147483647]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 2147483648}]})",
       "'id' is 2147483648, must be in [0, 2147483647]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": -1}]})", "'id' is -1, must be in [0, 2147483647]"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 18446744073709551615}]})",
       "'id' is 18446744073709551615, must be in [0, 2147483647]"},
      {R"({"mesh": "scene_mesh.ply", "albedo_texture": "a.exr"})", "has no valid uv"},
      {R"({"mesh": "missing.ply"})", "not found"},
      {R"({"mesh": "scene_mesh.ply", "model": 3})", "type must be string"},
      {R"({"mesh": "scene_mesh.ply", "objects": [{"id": 0, "name": 7}]})", "type must be string"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    const fs::path p = writeBytes("scene" + std::to_string(i) + ".json", cases[i].first);
    const std::string err = errorOf([&] { loadSceneFile(p); });
    EXPECT_NE(err.find(cases[i].second), std::string::npos) << i << ": " << err;
    EXPECT_NE(err.find(tmpDir().string()), std::string::npos) << "must name the file: " << err;
  }
}

TEST(SceneFile, RejectsTexelsOutsideTheirDomain) {
  MeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.uvs = {{0, 0}, {1, 0}, {0, 1}};
  m.triangles = {{0, 1, 2}};
  writePly(tmpDir() / "uv_mesh.ply", m);
  Image img(2, 2);
  std::fill(img.rgb.begin(), img.rgb.end(), 0.5f);
  img.rgb[3 * 3 + 1] = 1.5f;  // texel (1, 1), green
  writeExr(tmpDir() / "bright_albedo.exr", img);
  std::string err = errorOf([] {
    loadSceneFile(writeBytes("tex_albedo.json", R"({"mesh": "uv_mesh.ply", "albedo_texture": "bright_albedo.exr"})"));
  });
  EXPECT_NE(err.find((tmpDir() / "bright_albedo.exr").string() + ": texel (1, 1) channel 1 is 1.5, must be in [0, 1]"),
            std::string::npos)
      << err;
  img.rgb[3 * 3 + 1] = -2.0f;
  writeExr(tmpDir() / "negative_emission.exr", img);
  err = errorOf([] {
    loadSceneFile(writeBytes("tex_emission.json", R"({"mesh": "uv_mesh.ply", "objects": [{"id": 0,
      "emission_texture": "negative_emission.exr", "emission_window": [0, 0, 2, 2]}]})"));
  });
  EXPECT_NE(err.find("negative_emission.exr: texel (1, 1) channel 1 is -2, must be in [0, 1e8]"), std::string::npos)
      << err;
  img.rgb[3 * 3 + 1] = 1e9f;  // finite, but beyond the radiance bound
  writeExr(tmpDir() / "bright_emission.exr", img);
  err = errorOf([] {
    loadSceneFile(writeBytes("tex_bright_emission.json", R"({"mesh": "uv_mesh.ply", "objects": [{"id": 0,
      "emission_texture": "bright_emission.exr", "emission_window": [0, 0, 2, 2]}]})"));
  });
  EXPECT_NE(err.find("bright_emission.exr: texel (1, 1) channel 1 is 1000000000, must be in [0, 1e8]"), std::string::npos)
      << err;
  err = errorOf([] {
    loadSceneFile(writeBytes("window.json", R"({"mesh": "uv_mesh.ply", "objects": [{"id": 0,
      "emission_texture": "bright_albedo.exr", "emission_window": [0, 0, 4294967298, 2]}]})"));
  });
  EXPECT_NE(err.find("'emission_window[2]' is 4294967298"), std::string::npos) << err;
}

TEST(SceneFile, ModelDefaultsToPrincipledV1AndRoundTrips) {
  MeshData m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.triangles = {{0, 1, 2}};
  writePly(tmpDir() / "scene_mesh.ply", m);
  EXPECT_EQ(loadSceneFile(writeBytes("model_default.json", R"({"mesh": "scene_mesh.ply"})")).appearance.model,
            BsdfModel::PrincipledV1);
  SceneDescription s = loadSceneFile(writeBytes("model_gltf.json", R"({"mesh": "scene_mesh.ply", "model": "gltf"})"));
  EXPECT_EQ(s.appearance.model, BsdfModel::Gltf);
  fs::create_directories(tmpDir() / "roundtrip");
  saveSceneFile(tmpDir() / "roundtrip" / "scene.json", s);
  EXPECT_EQ(loadSceneFile(tmpDir() / "roundtrip" / "scene.json").appearance.model, BsdfModel::Gltf);
}
