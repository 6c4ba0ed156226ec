#include <gtest/gtest.h>

#include <fstream>

#include "lab/experiment.h"
#include "lab/profile.h"
#include "support/prepared_capture.h"

using namespace relume;
namespace fs = std::filesystem;

// `profile --what fit`: times the asked stage's iterations of a real fit and leaves the work
// folder as it was.
TEST(ProfileFit, TimesTheAskedStageAndWritesNothing) {
  const fs::path dir = smallPreparedRoom("profile_fit");
  const fs::path work = dir / "work";
  FitConfig c;
  c.batchTexels = 512;
  c.maxDepth = 3;
  // One emission iteration: emission starts at 0, so no light-source candidate has a light table
  // yet, and the fit's peak memory is the albedo stage's (with its Gauss-Newton state).
  c.emissionIterations = 1;
  const FitProfile p = profileFit(work, c, "albedo", 3);
  EXPECT_EQ(p.stage, "albedo@128");
  ASSERT_EQ(p.perIteration.size(), 3u);
  for (const FitPhaseTimes& t : p.perIteration) {
    EXPECT_GT(t.sample, 0);
    EXPECT_GT(t.primal, 0);
    EXPECT_GT(t.adjoint, 0);
    EXPECT_GT(t.optimiser, 0);  // the albedo steps in this stage
  }
  ASSERT_GT(p.raysPerIteration, 0u);
  EXPECT_GE(p.primalClosestRays, p.raysPerIteration);  // every path traces at least its camera ray
  EXPECT_GT(p.primalTraceOnly, 0);
  EXPECT_GT(p.adjointNoScatter, 0);
  // The albedo at 128^2 (RGB floats) is among the parameters the fit holds, and its state with it.
  EXPECT_GE(p.memory["parameters"].get<double>(), 128.0 * 128 * 3 * 4);
  EXPECT_GE(p.memory["optimiser_state"].get<double>(), 128.0 * 128 * 3 * 4);
  EXPECT_GT(p.memory["total"].get<double>(), p.memory["parameters"].get<double>());
  // The whole iteration over the primal, means of the timed iterations (what the bound is on).
  double total = 0, primal = 0;
  for (const FitPhaseTimes& t : p.perIteration) total += t.total(), primal += t.primal;
  EXPECT_NEAR(p.toJson()["iteration_over_primal"].get<double>(), total / primal, 1e-9 * total / primal);
  EXPECT_GT(total, primal);
  for (const char* f : {"metrics.jsonl", "checkpoint.bin", "result"}) EXPECT_FALSE(fs::exists(work / f)) << f;
  EXPECT_THROW(profileFit(work, c, "no-such-stage", 1), Error);
}

namespace {
std::vector<float> readFloats(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  std::vector<float> v((fs::file_size(path) + sizeof(float) - 1) / sizeof(float));
  f.read(reinterpret_cast<char*>(v.data()), static_cast<std::streamsize>(fs::file_size(path)));
  return v;
}
}  // namespace

// `profile --what render --rays-out`: the file holds exactly the rays replayed through Embree, as
// the paths traced them: with depth 0 each pixel sample's camera ray alone, from the camera.
TEST(ProfileRender, WritesTheRaysItReplays) {
  const SynthScene s = makeSynthScene(SynthSceneKind::Room, 64);
  const Camera cam = synthCameraPath(SynthSceneKind::Room, 8, 16, 12, 0.0)[2];
  const fs::path dir = fs::path(testing::TempDir()) / "relume_profile_rays";
  fs::create_directories(dir);
  const RenderProfile direct = profileRender(s.scene, cam, 2, 0, dir / "depth0.bin");
  EXPECT_EQ(direct.closestRays, 16u * 12 * 2);  // the room is closed: every camera ray hits
  EXPECT_EQ(direct.shadowRays, 0u);
  const std::vector<float> d0 = readFloats(dir / "depth0.bin");
  ASSERT_EQ(d0.size(), 8 * direct.closestRays);
  for (size_t i = 0; i < d0.size(); i += 8) {
    EXPECT_EQ(Vec3(d0[i], d0[i + 1], d0[i + 2]), cam.position);
    EXPECT_NEAR(Vec3(d0[i + 3], d0[i + 4], d0[i + 5]).norm(), 1.0f, 1e-5f);
    EXPECT_EQ(d0[i + 6], INFINITY);
    EXPECT_EQ(d0[i + 7], 0.0f);
  }
  const RenderProfile deep = profileRender(s.scene, cam, 2, 3, dir / "depth3.bin");
  const std::vector<float> d3 = readFloats(dir / "depth3.bin");
  ASSERT_EQ(d3.size(), 8 * (deep.closestRays + deep.shadowRays));
  size_t shadow = 0;
  for (size_t i = 0; i < d3.size(); i += 8) {
    const bool isShadow = d3[i + 7] == 1.0f;
    shadow += isShadow;
    EXPECT_EQ(std::isfinite(d3[i + 6]), isShadow);  // shadow rays end at the light, closest hits do not
  }
  EXPECT_EQ(shadow, deep.shadowRays);
  EXPECT_GT(deep.closestRays, direct.closestRays);
}

// `profile --what adjoint`: Embree alone replays the rays of the primal and of the adjoint pass;
// with depth 0 each pass traces one ray per batch ray.
TEST(ProfileAdjoint, ReplaysBothPassesRaysThroughEmbree) {
  ExperimentOptions eo;
  eo.rays = 300;
  eo.maxDepth = 0;
  const GradientExperiment e = makeGradientExperiment(SynthSceneKind::Room, eo);
  const AdjointProfile direct = profileAdjoint(e.truth, e.current, e.rays, 0, 1);
  EXPECT_EQ(direct.primalRaysTraced, e.rays.size());
  EXPECT_EQ(direct.adjointRaysTraced, e.rays.size());
  EXPECT_GT(direct.primalTraceOnly, 0);
  EXPECT_GT(direct.adjointTraceOnly, 0);
  EXPECT_EQ(direct.traceOnlyFloor(), direct.primalTraceOnly + direct.adjointTraceOnly);
  const AdjointProfile deep = profileAdjoint(e.truth, e.current, e.rays, 4, 1);
  EXPECT_GT(deep.primalRaysTraced, 2 * e.rays.size());  // closest hits and shadow rays at every vertex
  EXPECT_GT(deep.adjointRaysTraced, 2 * e.rays.size());
  EXPECT_GT(deep.peakRssMiB, 0);
}
