// `relume synth --imperfect`: the spec's parser, and known answers on tiny captures compared with
// the clean capture of the same seed.
#include "scenes/imperfections.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <OpenImageIO/imageio.h>
#include <fstream>
#include <iterator>

#include "capture/frame_image.h"
#include "capture/objects.h"
#include "capture/transforms.h"
#include "core/error.h"
#include "io/json.h"
#include "io/mesh_data.h"
#include "scenes/degrade.h"
#include "scenes/synth.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

std::string errorOf(const std::string& spec) {
  try {
    (void)parseImperfections(spec);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(ImperfectSpec, ParsesTheExample) {
  const ImperfectionSpec s = parseImperfections(
      "pose=1cm,0.3deg;bracket=-1.5,0,1.5;wb=0.03;noise=1000,0.002;ldr=8;mesh=5mm;"
      "segmentation=none;missing=9;exposure-drift=0.1");
  ASSERT_TRUE(s.pose);
  EXPECT_DOUBLE_EQ(s.pose->translation.metres(), 0.01);
  EXPECT_DOUBLE_EQ(s.pose->rotation.radians(), 0.3 * kPi / 180);
  EXPECT_EQ(s.bracketStops, (std::vector<double>{-1.5, 0, 1.5}));
  EXPECT_EQ(s.whiteBalance, 0.03);
  EXPECT_EQ(s.exposureDrift, 0.1);
  ASSERT_TRUE(s.noise);
  EXPECT_EQ(s.noise->photons, 1000);
  EXPECT_EQ(s.noise->readSigma, 0.002);
  EXPECT_EQ(s.ldrBits, 8);
  ASSERT_TRUE(s.meshNoise);
  EXPECT_DOUBLE_EQ(s.meshNoise->metres(), 0.005);
  EXPECT_FALSE(s.segmentation);
  EXPECT_EQ(s.missingPercent, 9);
  EXPECT_EQ(parseImperfections(""), ImperfectionSpec{});
  EXPECT_EQ(parseImperfections(" wb = 0.1 ; ldr = 16 ").ldrBits, 16);  // blanks around keys and values
}

TEST(ImperfectSpec, RoundTripsThroughToString) {
  for (const char* spec : {"", "pose=1cm,0.3deg", "pose=0.5mm,0.001rad", "pose=1e-05m,0deg", "bracket=-1.5,0,1.5",
                           "bracket=2", "wb=0.03;exposure-drift=0.2", "noise=1000,0.002", "noise=100000000000,0.5",
                           "ldr=16", "mesh=5mm", "segmentation=none", "missing=12.5", "absent=sofa", "unseen=light",
                           "pose=1cm,0.3deg;bracket=-1.5,0,1.5;wb=0.03;exposure-drift=0.1;noise=1000,0.002;ldr=8;"
                           "mesh=5mm;segmentation=none;missing=9"}) {
    const ImperfectionSpec s = parseImperfections(spec);
    EXPECT_EQ(toString(s), spec);
    EXPECT_EQ(parseImperfections(toString(s)), s) << spec;
  }
  // Any order and spelling gives the canonical string.
  EXPECT_EQ(toString(parseImperfections("missing=9; ldr=8.0 ;pose=1cm,0.30deg")), "pose=1cm,0.3deg;ldr=8;missing=9");
}

TEST(ImperfectSpec, EveryMalformedSpecIsAOneLineErrorNamingTheKey) {
  const std::pair<const char*, const char*> cases[] = {
      {"blur=3", "'blur' is unknown (keys: pose, bracket"},
      {"pose", "'pose' is not KEY=VALUE"},
      {"pose=", "'pose' has an empty value"},
      {"wb=0.1;;ldr=8", "has an empty item"},
      {"wb=0.1;", "has an empty item"},
      {"wb=0.1;wb=0.2", "'wb' is given twice"},
      {"pose=1,0.3deg", "'pose': translation '1' needs a unit (mm, cm or m)"},
      {"pose=1cm,0.3", "'pose': rotation '0.3' needs a unit (deg or rad)"},
      {"pose=1km,0.3deg", "translation '1km' must be a number with a unit (mm, cm or m)"},
      {"pose=1cm", "'pose': expected D,A"},
      {"pose=1cm,0.3deg,2", "'pose': expected D,A"},
      {"pose=-1cm,0.3deg", "'pose': translation is -1, must be in [0, 100] cm"},
      {"pose=2m,0.3deg", "translation is 2, must be in [0, 1]"},
      {"pose=1cm,90deg", "rotation is 90, must be in [0, 45] deg"},
      {"pose=nancm,1deg", "must be a number with a unit"},
      {"bracket=1,,2", "'bracket': empty number"},
      {"bracket=1,x", "'bracket': stop 'x' is not a number"},
      {"bracket=30", "'bracket': stop is 30, must be in [-20, 20]"},
      {"bracket=0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0", "'bracket': expected 1 to 16 stops"},
      {"wb=-0.1", "'wb': log-gain sigma is -0.1, must be in [0, 1]"},
      {"wb=inf", "'wb': log-gain sigma 'inf' is not a number"},
      {"wb=0.1,0.2", "'wb': expected one sigma"},
      {"exposure-drift=5", "'exposure-drift': log-gain sigma is 5, must be in [0, 1]"},
      {"noise=1000", "'noise': expected F,R"},
      {"noise=0.5,0", "'noise': photons is 0.5, must be in [1, 1e+12]"},
      {"noise=1000,-1", "'noise': read-noise sigma is -1, must be in [0, 1]"},
      {"ldr=12", "'ldr': bit depth '12' must be 8 or 16"},
      {"ldr=eight", "'ldr': bit depth 'eight' must be 8 or 16"},
      {"mesh=5", "'mesh': displacement '5' needs a unit"},
      {"mesh=1m", "'mesh': displacement is 1, must be in [0, 0.5] m"},
      {"segmentation=some", "'segmentation': 'some' is not allowed (only 'none')"},
      {"missing=99", "'missing': percentage is 99, must be in [0, 95]"},
      {"missing=9%", "'missing': percentage '9%' is not a number"},
      {"absent=sofa,cube", "'absent': 'sofa,cube' must be one object's name"},
      {"unseen=light b", "'unseen': 'light b' must be one object's name"},
      {"=3", "imperfection '' is unknown"},
      {"wb=0.1\nldr=8", "control character 0x0a at byte 6"},
  };
  for (const auto& [spec, message] : cases) {
    const std::string e = errorOf(spec);
    EXPECT_NE(e.find(message), std::string::npos) << spec << ": " << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << spec;
  }
}

namespace {

// A tiny Cornell capture in a folder of this test process, clean or with flaws.
class ImperfectCapture : public testing::Test {
 protected:
  const fs::path root = fs::temp_directory_path() / fmt::format("relume_imperfect_test_{}", getpid());
  void TearDown() override { fs::remove_all(root); }

  SynthCaptureOptions options(const std::string& name, const std::optional<std::string>& spec,
                              uint64_t seed = 7) const {
    SynthCaptureOptions o;
    o.kind = SynthSceneKind::Cornell;
    o.out = root / name;
    o.frames = 4, o.testFrames = 1, o.width = 64, o.height = 48, o.spp = 2, o.testSpp = 1, o.atlasResolution = 64;
    o.maxDepth = 3;
    o.seed = seed;
    if (spec) o.imperfections = parseImperfections(*spec);
    return o;
  }
  fs::path write(const std::string& name, const std::optional<std::string>& spec, uint64_t seed = 7) const {
    writeSynthCapture(options(name, spec, seed));
    return root / name;
  }
};

// A file's bytes, except the capture date OpenImageIO stamps into every EXR header (to the
// second), which would make two identical captures differ.
std::string bytesOf(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const std::string tag("capDate\0string\0", 15);
  if (const size_t at = bytes.find(tag); file.extension() == ".exr" && at != std::string::npos)
    bytes.replace(at + tag.size() + 4, 19, 19, '-');  // after the attribute's 4-byte size: "YYYY:MM:DD hh:mm:ss"
  return bytes;
}

// Every regular file under `dir`, relative path -> bytes.
std::map<std::string, std::string> filesOf(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) files[fs::relative(e.path(), dir).generic_string()] = bytesOf(e.path());
  return files;
}

// The raw pixel values of an 8-bit image and its stored bit depth.
std::vector<uint8_t> pixels8(const fs::path& file, int& bits) {
  auto in = OIIO::ImageInput::open(file.string());
  EXPECT_TRUE(in) << file;
  if (!in) return {};
  const OIIO::ImageSpec& spec = in->spec();
  bits = static_cast<int>(spec.format.size() * 8);
  std::vector<uint8_t> v(static_cast<size_t>(spec.width) * spec.height * spec.nchannels);
  in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UINT8, v.data());
  return v;
}

}  // namespace

TEST_F(ImperfectCapture, AnEmptySpecWritesTheCleanCapturePlusItsTruth) {
  const auto clean = filesOf(write("clean", std::nullopt)), empty = filesOf(write("empty", ""));
  auto withoutTruth = empty;
  EXPECT_EQ(withoutTruth.erase("gt/imperfections.json"), 1u);
  EXPECT_EQ(withoutTruth, clean);
}

TEST_F(ImperfectCapture, BracketIsRecordedAndScalesThePixels) {
  const fs::path clean = write("clean", std::nullopt), cap = write("bracket", "bracket=-1,0,2");
  const Capture c = readTransforms(clean / "transforms.json"), b = readTransforms(cap / "transforms.json");
  ASSERT_EQ(b.frames.size(), 4u);
  const float expected[] = {0.5f, 1.0f, 4.0f, 0.5f};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(b.frames[i].exposure, expected[i]) << i;
    EXPECT_TRUE(b.frames[i].exposureRecorded) << i;
    // On disk the pixels are the radiance times 2^E, exactly (a power of two); read back, the radiance.
    const Image raw = readImage(b.frames[i].image), truth = readImage(c.frames[i].image);
    ASSERT_EQ(raw.rgb.size(), truth.rgb.size());
    for (size_t k = 0; k < raw.rgb.size(); ++k) ASSERT_EQ(raw.rgb[k], truth.rgb[k] * expected[i]) << i << " " << k;
    EXPECT_EQ(loadFrameImage(b.frames[i]).rgb, truth.rgb) << i;
  }
  // The held-out frames are the judge: untouched.
  EXPECT_EQ(bytesOf(cap / "transforms_test.json"), bytesOf(clean / "transforms_test.json"));
  EXPECT_EQ(bytesOf(cap / "test" / "frame_0000.exr"), bytesOf(clean / "test" / "frame_0000.exr"));
}

TEST_F(ImperfectCapture, Ldr8FramesClipAtOneAndQuantiseTheExposedGainedRadiance) {
  const fs::path clean = write("clean", std::nullopt), cap = write("ldr", "ldr=8;bracket=1;wb=0.05");
  const Json truth = readJson(cap / "gt" / "imperfections.json");
  const Capture c = readTransforms(clean / "transforms.json"), l = readTransforms(cap / "transforms.json");
  ASSERT_EQ(l.frames.size(), 4u);
  size_t saturated = 0, unsaturated = 0;
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_EQ(l.frames[i].image.extension(), ".png");
    int bits = 0;
    const std::vector<uint8_t> code = pixels8(l.frames[i].image, bits);
    EXPECT_EQ(bits, 8);
    const Image radiance = readImage(c.frames[i].image);
    ASSERT_EQ(code.size(), radiance.rgb.size());
    const Json& f = truth["frames"][i];
    for (size_t k = 0; k < code.size(); ++k) {
      const float v = radiance.rgb[k] * 2.0f * f["wb_gain"][k % 3].get<float>();
      if (v >= 1.0f) {
        ASSERT_EQ(code[k], 255) << i << " " << k << " " << v;
        ++saturated;
      } else {
        ASSERT_LE(std::abs(linearToSrgb(v) * 255.0f - code[k]), 0.5f + 1e-3f) << i << " " << k << " " << v;
        ++unsaturated;
      }
    }
  }
  EXPECT_GT(saturated, 20u);  // the lamp
  EXPECT_GT(unsaturated, 1000u);
}

TEST_F(ImperfectCapture, GainsInTheTruthAreTheRatiosToTheCleanFrames) {
  const fs::path clean = write("clean", std::nullopt), cap = write("wb", "wb=0.1;exposure-drift=0.2");
  const Json truth = readJson(cap / "gt" / "imperfections.json");
  const Capture c = readTransforms(clean / "transforms.json"), w = readTransforms(cap / "transforms.json");
  ASSERT_EQ(w.frames.size(), 4u);
  std::vector<float> gains;
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_FALSE(w.frames[i].exposureRecorded) << "gains are not recorded";
    const Json& f = truth["frames"][i];
    const Image a = readImage(w.frames[i].image), b = readImage(c.frames[i].image);
    for (int ch = 0; ch < 3; ++ch) {
      const float gain = f["wb_gain"][ch].get<float>() * f["exposure_drift_gain"].get<float>();
      gains.push_back(gain);
      for (size_t k = ch; k < a.rgb.size(); k += 3)
        ASSERT_NEAR(a.rgb[k], b.rgb[k] * gain, 1e-6f * b.rgb[k] * gain) << i << " " << k;
    }
  }
  // The gains differ by frame and channel, by about the sigmas given.
  EXPECT_GT(*std::max_element(gains.begin(), gains.end()) / *std::min_element(gains.begin(), gains.end()), 1.05f);
}

TEST_F(ImperfectCapture, WrittenPosesAreOffByExactlyTheGivenDistanceAndAngle) {
  const fs::path clean = write("clean", std::nullopt), cap = write("pose", "pose=1cm,0.3deg");
  const Json truth = readJson(cap / "gt" / "imperfections.json");
  const Capture c = readTransforms(clean / "transforms.json"), p = readTransforms(cap / "transforms.json");
  ASSERT_EQ(p.frames.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    const Camera &written = p.frames[i].camera, &exact = c.frames[i].camera;
    EXPECT_NEAR((written.position - exact.position).norm(), 0.01f, 2e-6f) << i;
    const Eigen::AngleAxisd turn((written.rotation * exact.rotation.transpose()).cast<double>());
    EXPECT_NEAR(turn.angle() * 180 / kPi, 0.3, 1e-3) << i;
    // The truth holds the clean pose and the written one; the image is the clean frame.
    EXPECT_EQ(truth["frames"][i]["true_transform_matrix"], cameraToWorldJson(exact)) << i;
    EXPECT_EQ(truth["frames"][i]["written_transform_matrix"], cameraToWorldJson(written)) << i;
    EXPECT_EQ(bytesOf(p.frames[i].image), bytesOf(c.frames[i].image)) << i;
  }
  EXPECT_EQ(bytesOf(cap / "transforms_test.json"), bytesOf(clean / "transforms_test.json"));
}

TEST_F(ImperfectCapture, MeshVerticesMoveAtMostTheGivenDistanceTogetherAndTheSegmentationCanGo) {
  const fs::path clean = write("clean", std::nullopt), cap = write("mesh", "mesh=5mm;segmentation=none");
  const MeshData a = readPly(clean / "mesh.ply"), b = readPly(cap / "mesh.ply");
  ASSERT_EQ(a.positions.size(), b.positions.size());
  EXPECT_EQ(a.triangles, b.triangles);
  double largest = 0, sum = 0;
  for (size_t v = 0; v < a.positions.size(); ++v) {
    const double d = (b.positions[v] - a.positions[v]).cast<double>().norm();
    largest = std::max(largest, d);
    sum += d;
  }
  EXPECT_LE(largest, 0.005 + 1e-6);
  EXPECT_GT(sum / a.positions.size(), 0.002);  // uniform in the ball: mean 3/4 of the radius
  // Coincident vertices (patch seams) stay coincident: the mesh is not torn.
  size_t coincident = 0;
  for (size_t v = 0; v < a.positions.size(); ++v)
    for (size_t u = v + 1; u < a.positions.size(); ++u)
      if ((a.positions[u] - a.positions[v]).norm() < 1e-6f) {
        ++coincident;
        EXPECT_LT((b.positions[u] - b.positions[v]).norm(), 1e-6f) << u << " " << v;
      }
  EXPECT_GT(coincident, 10u);
  // The true mesh is kept; the segmentation is gone from the mesh and as objects.json.
  EXPECT_EQ(bytesOf(cap / "gt" / "mesh_clean.ply"), bytesOf(clean / "mesh.ply"));
  EXPECT_FALSE(a.faceObject.empty());
  EXPECT_TRUE(b.faceObject.empty());
  EXPECT_TRUE(fs::exists(clean / "objects.json"));
  EXPECT_FALSE(fs::exists(cap / "objects.json"));
  EXPECT_NEAR(readJson(cap / "gt" / "imperfections.json")["parsed"]["mesh"]["largest_offset_m"].get<double>(), largest,
              1e-6);
}

TEST_F(ImperfectCapture, AnAbsentObjectLeavesTheMeshAndStaysInTheTruth) {
  const fs::path clean = write("clean", std::nullopt), cap = write("absent", "absent=tall_box;mesh=5mm");
  const MeshData a = readPly(clean / "mesh.ply"), b = readPly(cap / "mesh.ply");
  int box = -1;
  for (const auto& [id, name] : readObjectNames(cap / "objects.json")) box = name == "tall_box" ? id : box;
  const size_t boxFaces = static_cast<size_t>(std::count(a.faceObject.begin(), a.faceObject.end(), box));
  EXPECT_GT(boxFaces, 0u);
  EXPECT_EQ(b.triangles.size(), a.triangles.size() - boxFaces);
  EXPECT_EQ(std::count(b.faceObject.begin(), b.faceObject.end(), box), 0);
  EXPECT_EQ(bytesOf(cap / "gt" / "mesh_clean.ply"), bytesOf(clean / "mesh.ply"));
  EXPECT_EQ(readJson(cap / "gt" / "imperfections.json")["parsed"]["absent_object"], "tall_box");
  try {
    write("absent_unknown", "absent=piano");
    FAIL() << "an object the scene lacks";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no object 'piano' (objects: white, red, "), std::string::npos) << e.what();
  }
}

// Cameras placed to see the Cornell box's light (looking up at it from above the tall box's top) and
// not to (looking down at the floor, or at the tall box's top from above it).
TEST(CamerasShowing, SeeAnObjectWhereAPixelCentreSeesItFirst) {
  const SynthScene cornell = makeSynthScene(SynthSceneKind::Cornell, 64, 0);
  const std::vector<std::string>& names = cornell.scene.appearance.names;
  auto looking = [](const Vec3& at, float upDown) {
    Camera c;
    c.width = 32, c.height = 24, c.fx = c.fy = 20, c.cx = 16, c.cy = 12;
    c.position = at;
    // Forward along +-y (world up/down); x right.
    c.rotation.col(0) = Vec3(1, 0, 0);
    c.rotation.col(2) = Vec3(0, upDown, 0);
    c.rotation.col(1) = c.rotation.col(2).cross(c.rotation.col(0));
    return c;
  };
  const std::vector<Camera> cameras = {looking(Vec3(1.0f, 1.3f, 1.0f), 1), looking(Vec3(1.0f, 1.0f, 1.0f), -1),
                                       looking(Vec3(0.62f, 1.5f, 0.78f), -1)};
  const std::vector<uint8_t> light =
      camerasShowing(cornell.scene.mesh.toData(), namedObject("unseen", "light", names), cameras);
  EXPECT_EQ(light, (std::vector<uint8_t>{1, 0, 0}));
  const std::vector<uint8_t> box =
      camerasShowing(cornell.scene.mesh.toData(), namedObject("unseen", "tall_box", names), cameras);
  EXPECT_EQ(box, (std::vector<uint8_t>{0, 1, 1}));
  EXPECT_THROW((void)namedObject("unseen", "lamp", names), Error);
}

// The frames that show the unseen object are left out and say so in the truth; the others are the
// clean capture's. When every frame shows it, nothing is written and the error says why.
TEST_F(ImperfectCapture, FramesShowingAnUnseenObjectAreLeftOut) {
  const fs::path clean = write("clean", std::nullopt);
  const Capture c = readTransforms(clean / "transforms.json");
  std::vector<Camera> walk;
  for (const Frame& f : c.frames) walk.push_back(f.camera);
  const MeshData mesh = readPly(clean / "mesh.ply");
  const std::vector<std::string> names = {"white", "red", "green", "light", "tall_box", "short_box"};
  int tried = 0;
  for (const std::string& object : names) {
    const std::vector<uint8_t> shows = camerasShowing(mesh, namedObject("unseen", object, names), walk);
    const int showing = static_cast<int>(std::count(shows.begin(), shows.end(), 1));
    if (showing == 0 || showing == 4) continue;
    ++tried;
    const fs::path cap = write("unseen", "unseen=" + object);
    const Json truth = readJson(cap / "gt" / "imperfections.json");
    EXPECT_EQ(truth["parsed"]["unseen_object"], object);
    EXPECT_EQ(readTransforms(cap / "transforms.json").frames.size(), static_cast<size_t>(4 - showing)) << object;
    for (int i = 0; i < 4; ++i) {
      EXPECT_EQ(truth["frames"][i]["shows_unseen"].get<bool>(), shows[i] != 0) << object << " " << i;
      EXPECT_EQ(truth["frames"][i]["left_out"].get<bool>(), shows[i] != 0) << object << " " << i;
      const fs::path image = cap / "images" / fmt::format("frame_{:04d}.exr", i);
      ASSERT_EQ(fs::exists(image), !shows[i]) << object << " " << i;
      if (!shows[i]) {
        EXPECT_EQ(bytesOf(image), bytesOf(c.frames[i].image)) << object << " " << i;
      }
    }
  }
  EXPECT_GT(tried, 0) << "no object is in some frames and not in others";
  const std::vector<uint8_t> white = camerasShowing(mesh, 0, walk);
  ASSERT_EQ(std::count(white.begin(), white.end(), 1), 4);  // the floor, ceiling and back wall are in every frame
  try {
    write("unseen_everywhere", "unseen=white");
    FAIL() << "no frame left";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'unseen=white': every one of the 4 training frames"), std::string::npos)
        << e.what();
  }
}

TEST_F(ImperfectCapture, MissingFramesAreLeftOutAndListedInTheTruth) {
  const fs::path clean = write("clean", std::nullopt), cap = write("missing", "missing=50");
  const Json truth = readJson(cap / "gt" / "imperfections.json");
  const Capture c = readTransforms(clean / "transforms.json"), m = readTransforms(cap / "transforms.json");
  ASSERT_EQ(truth["left_out"].size(), 2u);
  ASSERT_EQ(m.frames.size(), 2u);
  std::vector<int> kept;
  for (int i = 0; i < 4; ++i) {
    const bool out = truth["frames"][i]["left_out"].get<bool>();
    const fs::path image = cap / "images" / fmt::format("frame_{:04d}.exr", i);
    EXPECT_EQ(fs::exists(image), !out) << i;
    if (!out) kept.push_back(i);
  }
  ASSERT_EQ(kept.size(), 2u);
  for (size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(m.frames[k].image.filename(), c.frames[kept[k]].image.filename());
    EXPECT_EQ(bytesOf(m.frames[k].image), bytesOf(c.frames[kept[k]].image));
    EXPECT_EQ(m.frames[k].camera.position, c.frames[kept[k]].camera.position);
  }
}

TEST_F(ImperfectCapture, NoiseHasTheVarianceOfShotAndReadNoise) {
  const fs::path clean = write("clean", std::nullopt), cap = write("noise", "noise=200,0.01");
  const Capture c = readTransforms(clean / "transforms.json"), n = readTransforms(cap / "transforms.json");
  double sum = 0, sumSq = 0;
  size_t count = 0;
  for (size_t i = 0; i < 4; ++i) {
    const Image noisy = readImage(n.frames[i].image), truth = readImage(c.frames[i].image);
    for (size_t k = 0; k < noisy.rgb.size(); ++k) {
      const double v = truth.rgb[k];
      if (v < 0.1) continue;  // away from the clamp at 0
      const double z = (noisy.rgb[k] - v) / std::sqrt(v / 200 + 0.01 * 0.01);
      sum += z, sumSq += z * z, ++count;
    }
  }
  ASSERT_GT(count, 5000u);
  const double mean = sum / count, var = sumSq / count - mean * mean;
  EXPECT_NEAR(mean, 0.0, 0.05);
  EXPECT_NEAR(var, 1.0, 0.08);
}

TEST_F(ImperfectCapture, TheSameSeedGivesTheSameBytesAndAnotherSeedOtherFlaws) {
  const std::string spec =
      "pose=1cm,0.3deg;bracket=-1.5,0,1.5;wb=0.03;exposure-drift=0.1;noise=1000,0.002;ldr=16;mesh=5mm;"
      "segmentation=none;missing=25";
  const auto a = filesOf(write("a", spec)), b = filesOf(write("b", spec));
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b);
  EXPECT_EQ(readJson(root / "a" / "gt" / "imperfections.json")["spec"], spec);
  const auto other = filesOf(write("c", spec, 8));
  EXPECT_NE(other.at("transforms.json"), a.at("transforms.json"));
  EXPECT_NE(other.at("mesh.ply"), a.at("mesh.ply"));
}

// `relume degrade` on the clean capture is `synth --imperfect` on the scene: the same frames,
// cameras, mesh, segmentation and truth, byte for byte, with and without 8-bit frames.
TEST_F(ImperfectCapture, DegradingTheCleanCaptureWritesWhatSynthImperfectWrites) {
  const fs::path clean = write("clean", std::nullopt);
  for (const std::string spec :
       {"pose=1cm,0.3deg;bracket=-1.5,0,1.5;wb=0.03;exposure-drift=0.1;noise=1000,0.002;ldr=8;mesh=5mm;"
        "segmentation=none;missing=25",
        "pose=2mm,0.1deg;wb=0.05;noise=500,0.001;mesh=1cm;absent=tall_box"}) {
    const auto direct = filesOf(write("direct", spec));
    DegradeOptions o;
    o.capture = clean, o.out = root / "degraded", o.spec = parseImperfections(spec), o.seed = 7;
    fs::remove_all(o.out);
    const DegradeSummary s = degradeCapture(o);
    EXPECT_EQ(s.framesWritten + s.framesLeftOut, 4);
    EXPECT_EQ(s.heldOutCopied, 1);
    const auto degraded = filesOf(o.out);
    EXPECT_EQ(degraded.size(), direct.size()) << spec;
    for (const auto& [name, bytes] : direct)
      EXPECT_TRUE(degraded.count(name) && degraded.at(name) == bytes) << name << " differs, " << spec;
  }
}

// A held-out frame's albedo pass (`albedo_path`: a Cycles capture's, for eval's per-pixel
// albedo) comes along with it; without it eval of the degraded capture stopped at the missing file.
TEST_F(ImperfectCapture, DegradeCopiesTheHeldOutFramesAlbedoPasses) {
  const fs::path clean = write("clean", std::nullopt);
  Capture heldOut = readTransforms(clean / "transforms_test.json");
  ASSERT_EQ(heldOut.frames.size(), 1u);
  Frame& f = heldOut.frames.front();
  f.albedo = clean / "test" / "00_albedo.exr";
  fs::copy_file(f.image, f.albedo);
  writeTransforms(clean / "transforms_test.json", heldOut.frames, heldOut.exactPoses);
  DegradeOptions o;
  o.capture = clean, o.out = root / "degraded", o.spec = parseImperfections("bracket=-1.5,0,1.5;ldr=8");
  EXPECT_EQ(degradeCapture(o).heldOutCopied, 1);
  const Capture copied = readTransforms(o.out / "transforms_test.json");
  ASSERT_EQ(copied.frames.size(), 1u);
  EXPECT_EQ(copied.frames.front().albedo, o.out / "test" / "00_albedo.exr");
  EXPECT_EQ(bytesOf(copied.frames.front().albedo), bytesOf(f.albedo));
}

TEST_F(ImperfectCapture, DegradeRefusesQuantisedFramesFlawedCapturesAndFoldersInUse) {
  const auto errorOfDegrade = [&](const fs::path& capture, const fs::path& out) -> std::string {
    DegradeOptions o;
    o.capture = capture, o.out = out, o.spec = parseImperfections("wb=0.03");
    try {
      degradeCapture(o);
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  };
  const fs::path ldr = write("ldr", "ldr=8"), flawed = write("flawed", "wb=0.1"), clean = write("clean", std::nullopt);
  const auto says = [](const std::string& error, std::initializer_list<const char*> parts) {
    for (const char* part : parts) EXPECT_NE(error.find(part), std::string::npos) << error << " lacks " << part;
  };
  fs::remove_all(ldr / "gt");  // an 8-bit capture as a camera gives it
  says(errorOfDegrade(ldr, root / "a"), {"frame_0000.png", "8-bit", "linear float"});
  EXPECT_FALSE(fs::exists(root / "a")) << "a half-written capture was left";
  says(errorOfDegrade(flawed, root / "b"), {"imperfections.json", "flaws already"});
  says(errorOfDegrade(clean, clean), {"must not be the source"});
  says(errorOfDegrade(clean, clean / "images"), {"not empty"});
  EXPECT_EQ(errorOfDegrade(clean, root / "c"), "(no error)");
}
