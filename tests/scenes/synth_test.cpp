#include "core/warp.h"
#include <gtest/gtest.h>

#include <set>

#include "capture/frame_image.h"
#include "scenes/synth.h"
#include "render/film.h"

using namespace relume;

TEST(Synth, RoomCameraPathSeesWallsFloorAndLights) {
  const SynthScene room = makeSynthScene(SynthSceneKind::Room, 256);
  const Scene scene(room.scene.mesh);
  std::set<int> seen;
  for (const Camera& c : synthCameraPath(SynthSceneKind::Room, 24, 64, 48, 0.0))
    for (int y = 0; y < c.height; y += 2)
      for (int x = 0; x < c.width; x += 2)
        if (const auto hit = scene.intersect(c.position, *c.rayDirection(Vec2(x + 0.5f, y + 0.5f))))
          seen.insert(hit->object);
  const Appearance& a = room.scene.appearance;
  for (const char* name :
       {"floor", "ceiling", "walls", "wallpaper_wall", "ceiling_light_a", "ceiling_light_b", "rug"}) {
    const int id = static_cast<int>(std::find(a.names.begin(), a.names.end(), name) - a.names.begin());
    ASSERT_LT(id, a.objectCount()) << name;
    EXPECT_TRUE(seen.count(id)) << name << " never seen";
  }
  EXPECT_GE(a.objectCount(), 12);
}

TEST(Synth, RoomIsClosedNoRayEscapes) {
  const SynthScene room = makeSynthScene(SynthSceneKind::Room, 256);
  const Scene scene(room.scene.mesh);
  Pcg32 rng(3);
  int misses = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 at = rng.next3D();
    const Vec3 o(0.3f + 4.4f * at.x(), 0.2f + 2.3f * at.y(), 0.3f + 3.4f * at.z());
    misses += !scene.intersect(o, squareToUniformSphere(rng.next2D()));
  }
  EXPECT_EQ(misses, 0);
}

TEST(Synth, CaptureRoundTripsThroughTheReaders) {
  const auto dir = std::filesystem::temp_directory_path() / "relume_synth_test";
  std::filesystem::remove_all(dir);
  SynthCaptureOptions o;
  o.kind = SynthSceneKind::Cornell;
  o.out = dir;
  o.frames = 2, o.testFrames = 1, o.width = 32, o.height = 24, o.spp = 2, o.testSpp = 2, o.atlasResolution = 64;
  EXPECT_EQ(writeSynthCapture(o), 3);
  const Capture cap = readTransforms(dir / "transforms.json");
  ASSERT_EQ(cap.frames.size(), 2u);
  const Image img = loadFrameImage(cap.frames[1]);
  double sum = 0;
  for (float v : img.rgb) sum += v;
  EXPECT_GT(sum, 0.0);
  const SceneDescription gt = loadSceneFile(dir / "gt" / "scene.json");
  EXPECT_TRUE(gt.mesh.hasUv());
  EXPECT_FALSE(loadMesh(dir / "mesh.ply").hasUv());  // captures carry no uv unless --with-uv
  EXPECT_GT(gt.appearance.emission[3].maxCoeff(), 0.0f);
  EXPECT_TRUE(cap.frames[0].camera.filter.isUnitBox());
  // Frames formed with another pixel filter say so, in both camera lists.
  o.pixelFilter = PixelFilter::parseSpec("blackman-harris");
  writeSynthCapture(o);
  for (const char* json : {"transforms.json", "transforms_test.json"})
    EXPECT_EQ(readTransforms(dir / json).frames[0].camera.filter, PixelFilter(PixelFilterType::BlackmanHarris, 1.5f))
        << json;
}

TEST(Synth, HeldOutViewsOfTheirOwnSizeLeaveTheTrainingFramesAsTheyWere) {
  const auto dir = std::filesystem::temp_directory_path() / "relume_synth_test_size";
  SynthCaptureOptions o;
  o.kind = SynthSceneKind::Cornell;
  o.frames = 2, o.testFrames = 2, o.width = 32, o.height = 24, o.spp = 2, o.testSpp = 2, o.atlasResolution = 64;
  std::vector<Image> frames[2];
  std::vector<Camera> tests[2];
  for (int run = 0; run < 2; ++run) {
    std::filesystem::remove_all(dir);
    o.out = dir;
    if (run == 1) o.testWidth = 16, o.testHeight = 12;
    writeSynthCapture(o);
    for (const Frame& f : readTransforms(dir / "transforms.json").frames) frames[run].push_back(loadFrameImage(f));
    for (const Frame& f : readTransforms(dir / "transforms_test.json").frames) {
      tests[run].push_back(f.camera);
      const Image img = loadFrameImage(f);
      EXPECT_EQ(img.width, f.camera.width);
      EXPECT_EQ(img.height, f.camera.height);
    }
  }
  ASSERT_EQ(frames[0].size(), 2u);
  for (size_t i = 0; i < frames[0].size(); ++i) EXPECT_EQ(frames[0][i].rgb, frames[1][i].rgb) << i;
  ASSERT_EQ(tests[1].size(), 2u);
  for (size_t i = 0; i < tests[1].size(); ++i) {
    EXPECT_EQ(tests[1][i].width, 16);
    EXPECT_EQ(tests[1][i].height, 12);
    EXPECT_FLOAT_EQ(tests[1][i].fx, tests[0][i].fx / 2);  // the same view, half the pixels across
    EXPECT_TRUE(tests[1][i].position.isApprox(tests[0][i].position));
  }
}
