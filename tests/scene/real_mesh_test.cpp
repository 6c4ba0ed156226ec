// End to end on a cut of a real artist-made room (tests/data/README.md): frames rendered by relume,
// then `prepare` and a render of the prepared mesh. The mesh has triangles whose vertex normals
// cancel out, faces whose normals all face away, coincident and zero-area faces, a non-manifold fin
// and a 1 mm part.
#include <gtest/gtest.h>

#include <filesystem>

#include "io/image.h"
#include "io/json.h"
#include "product/prepare.h"
#include "render/film.h"
#include "render/lights.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {
Camera lookingAt(const Vec3& from, const Vec3& at) {
  Camera c;
  c.width = 48, c.height = 36, c.fx = c.fy = 40, c.cx = 24, c.cy = 18;
  c.position = from;
  const Vec3 f = (at - from).normalized();
  const Vec3 up = std::abs(f.y()) < 0.9f ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
  const Vec3 x = up.cross(f).normalized();
  c.rotation.col(0) = x, c.rotation.col(1) = f.cross(x), c.rotation.col(2) = f;
  return c;
}

bool allFinite(const Image& img) {
  for (float v : img.rgb)
    if (!std::isfinite(v)) return false;
  return true;
}

Appearance lit(int objects) {
  Appearance a(objects);
  a.emission[0] = Color(1.0f, 0.9f, 0.8f);  // the cut glows, so every frame sees light
  return a;
}
}  // namespace

TEST(RealMesh, PrepareAndRenderFinishWithoutInvalidRaysOrNaN) {
  const fs::path dir = fs::temp_directory_path() / "relume_real_cut";
  fs::remove_all(dir);
  fs::create_directories(dir / "images");
  fs::copy_file(fs::path(RELUME_TEST_DATA) / "furnished_cut.ply", dir / "mesh.ply");
  const TriangleMesh mesh = loadMesh(dir / "mesh.ply");
  Eigen::AlignedBox3f box;
  for (const Vec3& p : mesh.positions) box.extend(p);
  const Vec3 centre = box.center();
  const float radius = box.sizes().norm();
  std::vector<Frame> frames;
  {
    const Scene scene(mesh);
    const Appearance appearance = lit(mesh.objectCount);
    const LightSampler lights(scene, appearance);
    RenderOptions ro;
    ro.spp = 4, ro.path.maxDepth = 3;
    for (int i = 0; i < 8; ++i) {
      const float a = 2 * kPi * i / 8;
      Frame f;
      f.camera = lookingAt(centre + radius * Vec3(std::cos(a), 0.5f * (i % 2) - 0.25f, std::sin(a)), centre);
      f.image = dir / "images" / fmt::format("{:02d}.exr", i);
      const Image img = renderImage(scene, appearance, lights, f.camera, ro).color;
      ASSERT_TRUE(allFinite(img)) << "frame " << i;
      writeExr(f.image, img);
      frames.push_back(f);
    }
    // A fish-eye camera one ray epsilon above the surface, looking at it: it sees a patch around it
    // (so it joins the visibility index), and the surface point under it is closer than the 2 ray
    // epsilons the occlusion test keeps off the camera (this made a negative tmax).
    Frame on;
    const auto& t = mesh.triangles[0];
    const Vec3 p = (mesh.positions[t[0]] + mesh.positions[t[1]] + mesh.positions[t[2]]) / 3;
    const Vec3 n = mesh.shadingNormal(0, Vec3::Constant(1.0f / 3)).value_or(mesh.faceNormal(0));
    on.camera = lookingAt(p + rayEpsilon(p) * n, p - n);
    on.camera.fx = on.camera.fy = 2;
    on.image = dir / "images" / "on_surface.exr";
    writeExr(on.image, renderImage(scene, appearance, lights, on.camera, ro).color);
    frames.push_back(on);
    EXPECT_EQ(scene.skippedRays(), 0u);
  }
  writeTransforms(dir / "transforms.json", frames);

  PrepareOptions o;
  o.resolutions = {1024};
  o.maxSpeed = 1e3f, o.maxAngularSpeed = 360;  // a ring of views, not a walk
  o.maxUnderexposed = 1;                       // the cut floats in black space
  prepareCapture(dir, dir / "work", o);
  const Json report = readJson(dir / "work" / "prepare.json");
  const Json& phases = report["phases"];
  EXPECT_EQ(phases["atlas"]["dropped_coincident"].get<int>(), 2);
  EXPECT_EQ(phases["atlas"]["dropped_degenerate"].get<int>(), 2);
  EXPECT_GE(phases["atlas"]["packing_efficiency"].get<double>(), 0.35);
  EXPECT_EQ(phases["visibility"]["skipped_rays"].get<size_t>(), 0u);
  EXPECT_EQ(phases["init"]["skipped_rays"].get<size_t>(), 0u);
  EXPECT_GT(phases["init"]["texels_geometric_normal"].get<size_t>(), 0u);  // the opposed vertex normals
  EXPECT_LT(phases["init"]["fraction_unobserved"].get<double>(), 0.9);
  EXPECT_TRUE(allFinite(readImage(dir / "work" / "albedo_init.exr")));

  // A short render of the prepared (atlas) mesh.
  const TriangleMesh atlas = loadMesh(dir / "work" / "atlas_mesh.ply");
  EXPECT_EQ(countUvOverlaps(atlas, 1), 0u);
  const Scene scene(atlas);
  const Appearance appearance = lit(atlas.objectCount);
  const LightSampler lights(scene, appearance);
  RenderOptions ro;
  ro.spp = 4, ro.path.maxDepth = 4;
  for (const Frame& f : frames) EXPECT_TRUE(allFinite(renderImage(scene, appearance, lights, f.camera, ro).color));
  EXPECT_EQ(scene.skippedRays(), 0u);
}
