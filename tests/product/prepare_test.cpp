#include <gtest/gtest.h>

#include <map>

#include <fstream>

#include "capture/frame_store.h"
#include "core/error.h"
#include "io/image.h"
#include "io/atomic_file.h"
#include "io/json.h"
#include "product/prepare.h"
#include "scene/texel_map.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// A 2 x 2 m floor seen from above by `n` cameras; frames in `highlighted` carry a bright
// highlight (radiance 20) over the floor's centre, the others see a uniform 0.3.
fs::path makeFloorCapture(const std::string& name, int n, const std::vector<int>& highlighted, float jumpFrame = -1) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir / "images");
  MeshData m;
  m.positions = {{-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}};  // normal +y
  m.faceObject = {0, 0};
  writePly(dir / "mesh.ply", m);
  std::vector<Frame> frames;
  for (int i = 0; i < n; ++i) {
    Frame f;
    Camera& c = f.camera;
    c.width = 64, c.height = 48, c.fx = c.fy = 40, c.cx = 32, c.cy = 24;
    c.position = Vec3(0.1f * (i % 3) - 0.1f, 2.0f, 0.1f * (i / 3) - 0.1f + (i == jumpFrame ? 3.0f : 0.0f));
    c.rotation.col(0) = Vec3(1, 0, 0), c.rotation.col(1) = Vec3(0, 0, 1),
    c.rotation.col(2) = Vec3(0, -1, 0);  // looking down
    Image img(c.width, c.height);
    const bool bright = std::find(highlighted.begin(), highlighted.end(), i) != highlighted.end();
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        const Vec3 d = *c.rayDirection(Vec2(x + 0.5f, y + 0.5f));
        const Vec3 p = c.position + (-c.position.y() / d.y()) * d;
        img.set(x, y, Color::Constant(bright && Vec2(p.x(), p.z()).norm() < 0.3f ? 20.0f : 0.3f));
      }
    // Pixel (0, 0) looks past the floor: a value of its own there keeps the frames' files distinct,
    // since prepare skips a repeated image (and refuses one shown from two poses).
    img.set(0, 0, Color::Constant(0.3f + 0.01f * i));
    f.image = dir / "images" / fmt::format("{:02d}.exr", i);
    writeExr(f.image, img);
    frames.push_back(f);
  }
  writeTransforms(dir / "transforms.json", frames);
  return dir;
}

// Mean initial value over texels within 0.15 m of the floor's centre.
float centreValue(const fs::path& work) {
  const TriangleMesh mesh = loadMesh(work / "atlas_mesh.ply");
  const Image init = readImage(work / "albedo_init.exr");
  const TexelMap map(mesh, init.width);
  double sum = 0;
  int n = 0;
  for (size_t t = 0; t < map.texelCount(); ++t)
    if (map.covered(t) && Vec2(map.point(mesh, t).x(), map.point(mesh, t).z()).norm() < 0.15f)
      sum += init.at(static_cast<int>(t % init.width), static_cast<int>(t / init.width))[0], ++n;
  EXPECT_GT(n, 10);
  return static_cast<float>(sum / n);
}

PrepareOptions smallOptions() {
  PrepareOptions o;
  o.resolutions = {256};
  o.atlas.gutterResolution = 256;
  o.tileTexels = 16;
  return o;
}

}  // namespace

TEST(Prepare, MedianSuppressesAMinorityHighlightMeanDoesNot) {
  const fs::path cap = makeFloorCapture("relume_prep_highlight", 9, {2, 6});
  PrepareOptions o = smallOptions();
  prepareCapture(cap, cap / "work_median", o);
  o.init = InitStatistic::Mean;
  prepareCapture(cap, cap / "work_mean", o);
  o.init = InitStatistic::Median;
  o.downscale = 2;
  prepareCapture(cap, cap / "work_half", o);
  const float median = centreValue(cap / "work_median"), mean = centreValue(cap / "work_mean");
  EXPECT_NEAR(median, 0.3f, 0.3f * 0.05f);
  EXPECT_NEAR(centreValue(cap / "work_half"), 0.3f, 0.3f * 0.05f);  // same answer from a downscaled cache
  EXPECT_GT(mean, 3.0f);                                            // (7 x 0.3 + 2 x 20) / 9 = 4.7
  const Json report = readJson(cap / "work_median" / "prepare.json");
  EXPECT_EQ(report["phases"]["init"]["statistic"], "median");
  EXPECT_LT(report["phases"]["init"]["fraction_unobserved"].get<double>(), 0.05);
}

TEST(Prepare, DropsJumpsAndSaturatedFramesWithReasons) {
  const fs::path cap = makeFloorCapture("relume_prep_drop", 9, {}, 4);
  // Saturate frame 7: clip_high below its radiance.
  Json t = readJson(cap / "transforms.json");
  t["frames"][7]["clip_high"] = 0.2;
  writeJson(cap / "transforms.json", t);
  const PrepareSummary s = prepareCapture(cap, cap / "work", smallOptions());
  EXPECT_EQ(s.frames, 9u);
  EXPECT_EQ(s.keptFrames, 7u);
  const Json report = readJson(cap / "work" / "prepare.json");
  const std::string dropped = report["phases"]["frames"]["dropped"].dump();
  EXPECT_NE(dropped.find("motion blur"), std::string::npos) << dropped;
  EXPECT_NE(dropped.find("overexposed"), std::string::npos) << dropped;
}

// A rerun on a current folder skips every phase: none of its outputs is written again.
TEST(Prepare, RerunSkipsEveryPhaseAndChangesNothing) {
  const fs::path cap = makeFloorCapture("relume_prep_rerun", 6, {});
  prepareCapture(cap, cap / "work", smallOptions());
  const char* outputs[] = {"atlas_mesh.ply", "frames.bin", "visibility.bin", "albedo_init.exr", "coverage.exr"};
  std::map<std::string, fs::file_time_type> written;
  for (const char* f : outputs) written[f] = fs::last_write_time(cap / "work" / f);
  const auto before = written["frames.bin"];
  prepareCapture(cap, cap / "work", smallOptions());
  for (const char* f : outputs)
    EXPECT_EQ(fs::last_write_time(cap / "work" / f), written[f]) << f << " was written again";
  // Touching an image invalidates the frame phase and what depends on it.
  const Image img = readImage(cap / "images" / "00.exr");
  writeExr(cap / "images" / "00.exr", img);
  prepareCapture(cap, cap / "work", smallOptions());
  EXPECT_NE(fs::last_write_time(cap / "work" / "frames.bin"), before);
}

TEST(Prepare, UpToDateRunDoesNotRewriteItsReport) {
  // So `prepare` succeeds on an up-to-date folder that is read-only.
  const fs::path cap = makeFloorCapture("relume_prep_readonly", 4, {});
  const fs::path report = cap / "work" / "prepare.json";
  prepareCapture(cap, cap / "work", smallOptions());
  const auto written = fs::last_write_time(report);
  const std::string text = readJson(report).dump();
  prepareCapture(cap, cap / "work", smallOptions());
  EXPECT_EQ(fs::last_write_time(report), written);
  EXPECT_EQ(readJson(report).dump(), text);
}

TEST(Prepare, TruncatedReportAndKilledRunsTemporariesDoNotBlockARebuild) {
  const fs::path cap = makeFloorCapture("relume_prep_truncated", 4, {});
  const fs::path work = cap / "work", report = work / "prepare.json";
  prepareCapture(cap, work, smallOptions());
  for (const bool force : {true, false}) {
    SCOPED_TRACE(force ? "--force" : "no --force");
    const std::string text = readJson(report).dump();
    std::ofstream(report, std::ios::trunc) << text.substr(0, text.size() / 2);
    std::ofstream(work / ".frames.tmp999999999.bin") << "left by a killed run";  // no such pid
    PrepareOptions o = smallOptions();
    o.force = force;
    EXPECT_NO_THROW(prepareCapture(cap, work, o));
    EXPECT_TRUE(readJson(report)["phases"].contains("init"));
    EXPECT_FALSE(fs::exists(work / ".frames.tmp999999999.bin"));
  }
}

TEST(FrameStore, RoundTripMaskingAndCorruptFiles) {
  const fs::path dir = fs::temp_directory_path() / "relume_framestore";
  fs::create_directories(dir);
  Image img(8, 4);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) img.set(x, y, Color(x * 0.1f, y * 0.5f, 1000.0f));
  img.set(5, 2, Color(NAN, 0, 0));
  writeExr(dir / "a.exr", img);
  Frame f;
  f.camera.width = 8, f.camera.height = 4;
  f.image = dir / "a.exr";
  const auto stats = writeFrameStore(dir / "frames.bin", {f, f});
  EXPECT_NEAR(stats[0].masked, 1.0f / 32, 1e-6f);
  const FrameStore store(dir / "frames.bin");
  ASSERT_EQ(store.frameCount(), 2u);
  EXPECT_NEAR(store.pixel(1, 3, 1)[0], 0.3f, 1e-3f);  // half precision
  EXPECT_NEAR(store.pixel(1, 3, 1)[2], 1000.0f, 1.0f);
  EXPECT_LT(store.pixel(0, 5, 2)[0], 0.0f);  // masked
  EXPECT_FALSE(store.bilinear(0, Vec2(5.5f, 2.5f)));
  EXPECT_TRUE(store.bilinear(0, Vec2(2.0f, 2.0f)));
  EXPECT_FALSE(store.bilinear(0, Vec2(0.2f, 2.0f)));  // outside the pixel centres
  // The pixel containing a point: its value and extent; nothing outside or where masked.
  const auto stored = store.pixelAt(1, Vec2(3.9f, 1.1f));
  ASSERT_TRUE(stored);
  EXPECT_NEAR(stored->value[0], 0.3f, 1e-3f);
  EXPECT_EQ(stored->corner, Vec2(3, 1));
  EXPECT_EQ(stored->size, 1.0f);
  EXPECT_FALSE(store.pixelAt(0, Vec2(5.5f, 2.5f)));
  EXPECT_FALSE(store.pixelAt(0, Vec2(-0.1f, 2.0f)));
  EXPECT_FALSE(store.pixelAt(0, Vec2(8.0f, 2.0f)));
  EXPECT_TRUE(store.pixelAt(0, Vec2(0.0f, 3.99f)));
  // Downscaled by 2: block means, addressed with the original pixel coordinates.
  Image flat(8, 4);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 8; ++x) flat.set(x, y, Color::Constant(static_cast<float>(x)));
  writeExr(dir / "b.exr", flat);
  f.image = dir / "b.exr";
  writeFrameStore(dir / "half.bin", {f}, 2);
  const FrameStore half(dir / "half.bin");
  EXPECT_EQ(half.stats(0).width, 4u);
  EXPECT_NEAR(half.pixel(0, 1, 0)[0], 2.5f, 1e-3f);  // mean of columns 2 and 3
  EXPECT_NEAR((*half.bilinear(0, Vec2(4.0f, 2.0f)))[0], 3.5f,
              1e-3f);                                    // original x = 4 -> halfway between blocks 1 and 2
  const auto block = half.pixelAt(0, Vec2(3.5f, 1.0f));  // original pixel 3 is in block 1: columns 2-3, rows 0-1
  ASSERT_TRUE(block);
  EXPECT_NEAR(block->value[0], 2.5f, 1e-3f);
  EXPECT_EQ(block->corner, Vec2(2, 0));
  EXPECT_EQ(block->size, 2.0f);
  EXPECT_THROW(writeFrameStore(dir / "bad_scale.bin", {f}, 0), Error);
  std::string bytes(64, 'x');
  writeTextAtomically(dir / "bad.bin", bytes);
  EXPECT_THROW(FrameStore(dir / "bad.bin"), Error);
  EXPECT_THROW(FrameStore(dir / "missing.bin"), Error);
}
