#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include "core/error.h"
#include "io/image.h"
#include "product/prepare.h"
#include "sampling/samplers.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// A 2 x 2 m floor (object 0) seen from above by 6 cameras, with a 0.6 m quad (object 1) hovering
// at 1 m, wound facing down: it hides part of the floor from some cameras, and they see its back
// (BSDFs are two-sided, so a wall wound away from the room is still observed).
// Pixel (x, y) of frame i has radiance (x, y, 0.1 + 0.1 i): a reference says which frame and
// which pixel it came from (exact in the frame cache's half floats).
fs::path makeCapture() {
  // One folder per test: CTest runs the tests of this file in parallel processes.
  const fs::path dir =
      fs::temp_directory_path() /
      ("relume_sampler_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
  fs::remove_all(dir);
  fs::create_directories(dir / "images");
  MeshData m;
  m.positions = {{-1, 0, -1},       {1, 0, -1},       {1, 0, 1},       {-1, 0, 1},
                 {-0.3f, 1, -0.3f}, {0.3f, 1, -0.3f}, {0.3f, 1, 0.3f}, {-0.3f, 1, 0.3f}};
  m.triangles = {{0, 2, 1}, {0, 3, 2}, {4, 5, 6}, {4, 6, 7}};
  m.faceObject = {0, 0, 1, 1};
  writePly(dir / "mesh.ply", m);
  std::vector<Frame> frames;
  for (int i = 0; i < 6; ++i) {
    Frame f;
    Camera& c = f.camera;
    c.width = 64, c.height = 48, c.fx = c.fy = 30, c.cx = 32, c.cy = 24;
    c.position = Vec3(0.4f * (i % 3) - 0.4f, 2.5f, 0.5f * (i / 3) - 0.25f);
    c.rotation.col(0) = Vec3(1, 0, 0), c.rotation.col(1) = Vec3(0, 0, 1), c.rotation.col(2) = Vec3(0, -1, 0);
    Image img(c.width, c.height);
    for (int y = 0; y < c.height; ++y)
      for (int x = 0; x < c.width; ++x) {
        float* p = &img.rgb[3 * (static_cast<size_t>(y) * c.width + x)];
        p[0] = static_cast<float>(x), p[1] = static_cast<float>(y), p[2] = 0.1f + 0.1f * i;
      }
    f.image = dir / "images" / fmt::format("{:02d}.exr", i);
    writeExr(f.image, img);
    frames.push_back(f);
  }
  writeTransforms(dir / "transforms.json", frames);
  PrepareOptions po;
  po.resolutions = {256};
  po.atlas.gutterResolution = 256;
  prepareCapture(dir, dir / "work", po);
  return dir;
}

struct Fixture {
  fs::path dir = makeCapture();
  TriangleMesh mesh = loadMesh(dir / "work" / "atlas_mesh.ply");
  Scene scene{mesh};
  TexelMap map{mesh, 256};
  VisibilityIndex vis = VisibilityIndex::read(dir / "work" / "visibility.bin");
  Capture cap = readTransforms(dir / "transforms.json");
  FrameStore store{dir / "work" / "frames.bin"};
  std::vector<uint32_t> texels;
  Fixture() {
    for (size_t t = 0; t < map.texelCount(); ++t)
      if (map.covered(t)) texels.push_back(static_cast<uint32_t>(t));
  }
  TrainingFrames frames() const { return {&cap.frames, &store, {0, 1, 2, 3, 4, 5}}; }
};

}  // namespace

TEST(TextureSampler, EveryRayFirstHitsItsSurfacePointWithThatFramesReference) {
  Fixture f;
  const TextureSpaceSampler sampler(f.scene, f.map, f.texels, f.vis, f.frames());
  const Batch b = sampler.sample(3, 0, {2048, 3, RayFootprint::Point});
  ASSERT_GT(b.rays.size(), 2000u);
  EXPECT_EQ(b.stats.slots, 2048u);
  EXPECT_GT(b.stats.notSeen, 0u);  // the hovering quad hides some of the floor
  size_t quadRays = 0;
  for (size_t j = 0; j < b.rays.size(); ++j) {
    const BatchRay& r = b.rays[j];
    const auto hit = f.scene.intersect(r.origin, r.dir);
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->object, b.object[j]);
    quadRays += hit->object == 1;
    // The reference is the pixel of the frame whose camera the ray starts at.
    int frame = -1;
    for (int i = 0; i < 6; ++i)
      if ((f.cap.frames[i].camera.position - r.origin).norm() < 1e-6f) frame = i;
    ASSERT_GE(frame, 0);
    EXPECT_NEAR(r.reference[2], 0.1f + 0.1f * frame, 1e-3f);
    // Bilinear at the surface point's projection (pixel centres at +0.5).
    const auto px = f.cap.frames[frame].camera.project(hit->p);
    ASSERT_TRUE(px);
    EXPECT_NEAR(r.reference[0], px->x() - 0.5f, 2e-3f);
    EXPECT_NEAR(r.reference[1], px->y() - 0.5f, 2e-3f);
  }
  // The quad is seen from its back: 0.18 of the 4.36 m^2 of surface, so about 4% of the rays.
  EXPECT_GT(quadRays, b.rays.size() / 50);
  // At most K rays per texel slot, slots in order.
  for (size_t j = 1; j < b.slot.size(); ++j) EXPECT_LE(b.slot[j - 1], b.slot[j]);
}

// Pixel footprint: each ray passes through a random point of the pixel its texel's point
// projects into and carries that pixel's value, so its expectation is the pixel; the adjoint pass
// goes through another point of that pixel, drawn independently.
TEST(TextureSampler, PixelFootprintRaysCrossThePixelWhoseValueTheyCarry) {
  Fixture f;
  const TextureSpaceSampler sampler(f.scene, f.map, f.texels, f.vis, f.frames());
  const Batch b = sampler.sample(3, 0, {2048, 3, RayFootprint::Pixel});
  ASSERT_GT(b.rays.size(), 2000u);
  // Where in its pixel each direction passes: uniform, so mean 0.5 and spread 1/sqrt(12).
  double sum[2][2] = {}, sq[2] = {}, cross = 0;
  for (const BatchRay& r : b.rays) {
    int frame = -1;
    for (int i = 0; i < 6; ++i)
      if ((f.cap.frames[i].camera.position - r.origin).norm() < 1e-6f) frame = i;
    ASSERT_GE(frame, 0);
    EXPECT_NEAR(r.reference[2], 0.1f + 0.1f * frame, 1e-3f);
    ASSERT_NE(r.adjointDirection(), r.dir);
    Vec2 offset[2];
    for (int pass = 0; pass < 2; ++pass) {
      const auto px = f.cap.frames[frame].camera.project(r.origin + (pass == 0 ? r.dir : r.adjointDirection()));
      ASSERT_TRUE(px);
      offset[pass] = *px - Vec2(r.reference[0], r.reference[1]);
      EXPECT_NEAR(offset[pass].x(), 0.5f, 0.501f);  // inside pixel (x, y), to rounding
      EXPECT_NEAR(offset[pass].y(), 0.5f, 0.501f);
      sum[pass][0] += offset[pass].x(), sum[pass][1] += offset[pass].y(),
          sq[pass] += std::pow(offset[pass].x() - 0.5, 2);
    }
    cross += (offset[0].x() - 0.5) * (offset[1].x() - 0.5);
  }
  const double n = static_cast<double>(b.rays.size());
  for (int pass = 0; pass < 2; ++pass) {
    EXPECT_NEAR(sum[pass][0] / n, 0.5, 0.03);
    EXPECT_NEAR(sum[pass][1] / n, 0.5, 0.03);
    EXPECT_NEAR(std::sqrt(sq[pass] / n), 1.0 / std::sqrt(12.0), 0.02);
  }
  EXPECT_NEAR(cross / n * 12.0, 0.0, 0.1);  // uncorrelated: same point would give 1
  // A point footprint has one direction for both passes.
  for (const BatchRay& r : sampler.sample(3, 0, {256, 3, RayFootprint::Point}).rays)
    EXPECT_EQ(r.adjointDirection(), r.dir);
}

// With the capture's pixel filter (Cycles' Blackman-Harris 1.5 here), a pixel-footprint ray is
// drawn from that filter around the pixel's centre: spread beyond the pixel, with the filter's
// standard deviation, in both passes and from both samplers.
TEST(TextureSampler, PixelFootprintRaysFollowTheCapturesPixelFilter) {
  Fixture f;
  const PixelFilter bh(PixelFilterType::BlackmanHarris, 1.5f);
  for (Frame& frame : f.cap.frames) frame.camera.filter = bh;
  double fx2 = 0, fsum = 0;  // the filter's variance, by Simpson's rule on its weight
  for (int i = 0; i < 3000; ++i) {
    const double h = 2.0 * bh.radius() / 3000, x = -bh.radius() + (i + 0.5) * h;
    fx2 += bh.weight(float(x)) * x * x * h, fsum += bh.weight(float(x)) * h;
  }
  const TextureSpaceSampler texture(f.scene, f.map, f.texels, f.vis, f.frames());
  const ImageSpaceSampler image(f.frames());
  for (const Batch& b : {texture.sample(3, 0, {2048, 3, RayFootprint::Pixel}),
                         image.sample(3, 0, 12000, f.scene, RayFootprint::Pixel)}) {
    ASSERT_GT(b.rays.size(), 2000u);
    double sum = 0, sq = 0, n = 0, outside = 0;
    for (const BatchRay& r : b.rays) {
      int frame = -1;
      for (int i = 0; i < 6; ++i)
        if ((f.cap.frames[i].camera.position - r.origin).norm() < 1e-6f) frame = i;
      ASSERT_GE(frame, 0);
      for (const Vec3& dir : {r.dir, r.adjointDirection()}) {
        const auto px = f.cap.frames[frame].camera.project(r.origin + dir);
        ASSERT_TRUE(px);
        const double dx = px->x() - r.reference[0] - 0.5;  // from the centre of the pixel the ray carries
        EXPECT_LE(std::abs(dx), bh.radius() + 1e-3);
        sum += dx, sq += dx * dx, n += 1, outside += std::abs(dx) > 0.5;
      }
    }
    EXPECT_NEAR(sum / n, 0.0, 0.02);
    EXPECT_NEAR(std::sqrt(sq / n), std::sqrt(fx2 / fsum), 0.02);
    EXPECT_GT(outside / n, 0.05);  // a box would keep every ray inside the pixel
  }
}

// Samples per connection: a point ray is repeated as it is (the solver seeds each copy on its
// own); a pixel-footprint ray draws its own points of the same pixel per sample.
TEST(TextureSampler, EachSampleOfAConnectionIsItsOwnRay) {
  Fixture f;
  const TextureSpaceSampler sampler(f.scene, f.map, f.texels, f.vis, f.frames());
  const Batch single = sampler.sample(3, 0, {512, 3, RayFootprint::Point});
  const Batch point = sampler.sample(3, 0, {512, 3, RayFootprint::Point, 3});
  ASSERT_EQ(point.rays.size(), 3 * single.rays.size());
  for (size_t j = 0; j < point.rays.size(); ++j) {
    EXPECT_EQ(point.rays[j].dir, single.rays[j / 3].dir);
    EXPECT_EQ(point.slot[j], single.slot[j / 3]);
  }
  const Batch pixel = sampler.sample(3, 0, {512, 3, RayFootprint::Pixel, 3});
  ASSERT_EQ(pixel.rays.size() % 3, 0u);
  ASSERT_GT(pixel.rays.size(), 3 * 400u);
  for (size_t j = 0; j < pixel.rays.size(); j += 3)
    for (size_t k = 1; k < 3; ++k) {
      EXPECT_EQ(pixel.slot[j + k], pixel.slot[j]);
      EXPECT_EQ(pixel.rays[j + k].origin, pixel.rays[j].origin);
      EXPECT_EQ(pixel.rays[j + k].reference[0], pixel.rays[j].reference[0]);  // the same pixel
      EXPECT_NE(pixel.rays[j + k].dir, pixel.rays[j].dir);
      EXPECT_NE(pixel.rays[j + k].adjointDir, pixel.rays[j].adjointDir);
    }
}

TEST(TextureSampler, SameBatchAtAnyThreadCount) {
  Fixture f;
  const TextureSpaceSampler sampler(f.scene, f.map, f.texels, f.vis, f.frames());
  Batch one;
  tbb::task_arena(1).execute([&] { one = sampler.sample(5, 7, {1024, 4}); });
  const Batch two = sampler.sample(5, 7, {1024, 4});
  ASSERT_EQ(one.rays.size(), two.rays.size());
  for (size_t j = 0; j < one.rays.size(); ++j) {
    EXPECT_EQ(one.rays[j].dir, two.rays[j].dir);
    EXPECT_EQ(one.rays[j].reference[0], two.rays[j].reference[0]);
  }
  const Batch other = sampler.sample(5, 8, {1024, 4});
  EXPECT_NE(other.rays.front().dir, one.rays.front().dir);
}

TEST(ImageSampler, RaysThroughRandomPixelsOfUsableFrames) {
  Fixture f;
  TrainingFrames tf = f.frames();
  tf.usable = {2};
  const Batch b = ImageSpaceSampler(tf).sample(1, 0, 512, f.scene, RayFootprint::Pixel);
  // The wide camera sees the floor in part of the image only: pixels that see nothing give no ray.
  EXPECT_EQ(b.stats.slots, 512u);
  EXPECT_EQ(b.rays.size() + b.stats.notSeen + b.stats.masked, 512u);
  ASSERT_GT(b.rays.size(), 50u);
  for (const BatchRay& r : b.rays) {
    EXPECT_LT((r.origin - f.cap.frames[2].camera.position).norm(), 1e-6f);
    EXPECT_NEAR(r.reference[2], 0.3f, 1e-3f);
    // The pixel both passes' directions cross is the one whose value the ray carries.
    ASSERT_NE(r.adjointDirection(), r.dir);
    for (const Vec3& dir : {r.dir, r.adjointDirection()}) {
      const auto px = f.cap.frames[2].camera.project(r.origin + dir);
      ASSERT_TRUE(px);
      EXPECT_NEAR(px->x(), r.reference[0] + 0.5f, 0.501f);
      EXPECT_NEAR(px->y(), r.reference[1] + 0.5f, 0.501f);
    }
  }
}

TEST(Observe, SeesEitherSideAndRejectsNonFiniteNormalsAndPointsAtTheCamera) {
  Fixture f;
  const Camera& cam = f.cap.frames[0].camera;
  const Vec3 p(0.9f, 0, 0.9f);
  EXPECT_TRUE(observe(f.scene, cam, p, Vec3(0, 1, 0)));
  EXPECT_TRUE(observe(f.scene, cam, p, Vec3(0, -1, 0)));  // the back of a two-sided surface
  // The back of the hovering quad, whose winding faces away from every camera.
  EXPECT_TRUE(observe(f.scene, cam, Vec3(0, 1, 0), Vec3(0, -1, 0)));
  EXPECT_FALSE(observe(f.scene, cam, p, Vec3(NAN, NAN, NAN)));
  EXPECT_FALSE(observe(f.scene, cam, cam.position, Vec3(0, 1, 0)));
}
