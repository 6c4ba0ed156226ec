// Pose refinement (product/pose_refinement.h) on the room: a frame rendered from a known pose is
// aligned from a wrong one back to it, a right pose stays, and a frame that shows nothing to
// align on is refused; in the fit, estimated poses are refined, exact ones are not, and a resumed
// fit keeps the refined poses.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>

#include "io/image.h"
#include "product/fit.h"
#include "product/pose_refinement.h"
#include "render/lights.h"
#include "scene/scene.h"
#include "scenes/synth.h"
#include "support/prepared_capture.h"
#include "support/small_fit_config.h"

using namespace relume;

namespace {

constexpr int kWidth = 160, kHeight = 120;

class PoseRefinement : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    room_ = new SynthScene(makeSynthScene(SynthSceneKind::Room, 256));
    scene_ = new Scene(room_->scene.mesh);
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete room_;
  }

  // What a frame from `camera` shows: the true appearance, 64 paths per pixel, on the frame's own grid.
  static AlignImage frameFrom(const Camera& camera, const Appearance& a) {
    return renderedTarget(*scene_, a, LightSampler(*scene_, a), camera, 64, 99, PathSettings{});
  }

  // The model rendered as the frame was (64 paths per pixel): the test is of the alignment, not of
  // the model's noise, which the fit's measurement covers (docs/notes).
  static FrameAlignment align(const Camera& from, const AlignImage& frame, const Appearance& a) {
    const LightSampler lights(*scene_, a);
    const AlignImage target = renderedTarget(*scene_, a, lights, targetGrid(from), 64, 5, PathSettings{});
    return alignFrame(*scene_, from, frame, target, PoseAlignSettings{});
  }

  // `c` moved by `metres` along `axis` (world) and turned by `degrees` about `turnAxis` (camera).
  static Camera moved(Camera c, const Vec3& axis, double metres, const Vec3& turnAxis, double degrees) {
    c.position += axis.normalized() * static_cast<float>(metres);
    c.rotation = c.rotation * Eigen::AngleAxisf(static_cast<float>(degrees * M_PI / 180), turnAxis.normalized()).matrix();
    return c;
  }

  // The mean distance in pixels between where `camera` and `truth` put the surface points `truth`
  // sees at its pixel centres.
  static double reprojectionError(const Camera& truth, const Camera& camera) {
    double sum = 0;
    int n = 0;
    for (int y = 0; y < truth.height; y += 4)
      for (int x = 0; x < truth.width; x += 4) {
        const auto dir = truth.rayDirection(Vec2(x + 0.5f, y + 0.5f));
        const auto hit = dir ? scene_->intersect(truth.position, *dir) : std::nullopt;
        const auto q = hit ? camera.project(hit->p) : std::nullopt;
        if (!q) continue;
        sum += (*q - Vec2(x + 0.5f, y + 0.5f)).norm(), ++n;
      }
    return n ? sum / n : INFINITY;
  }

  static SynthScene* room_;
  static Scene* scene_;
};

SynthScene* PoseRefinement::room_ = nullptr;
Scene* PoseRefinement::scene_ = nullptr;

TEST_F(PoseRefinement, AWrongPoseIsAlignedBackToTheTrueOne) {
  const Appearance& truth = room_->scene.appearance;
  const std::vector<Camera> path = synthCameraPath(SynthSceneKind::Room, 4, kWidth, kHeight, 0.0);
  int within = 0;
  for (size_t i = 0; i < path.size(); ++i) {
    SCOPED_TRACE(i);
    const AlignImage frame = frameFrom(path[i], truth);
    // 1 cm and 0.3 degrees, the perturbation, in a different direction per frame.
    const Camera wrong = moved(path[i], Vec3(1, 0.3f * i, -0.5f), 0.01, Vec3(0.2f, 1, 0.1f * i), 0.3);
    const FrameAlignment a = align(wrong, frame, truth);
    EXPECT_EQ(a.status, AlignStatus::Aligned) << a.why;
    EXPECT_LT(a.costAfter, a.costBefore);
    // What the fit needs: each surface point the frame sees lands on its pixel again.
    EXPECT_GT(reprojectionError(path[i], wrong), 0.5);
    EXPECT_LT(reprojectionError(path[i], a.camera), 0.2);
    within += poseTranslation(path[i], a.camera) < 0.003 && poseRotationDeg(path[i], a.camera) < 0.1;
  }
  // The pose itself: a view of one far wall barely tells a sideways move from a turn (frame 3:
  // 11 mm and 0.24 deg along that direction, with its points still on their pixels).
  EXPECT_GE(within, 3);
}

TEST_F(PoseRefinement, ARightPoseStaysWhereItIs) {
  const Appearance& truth = room_->scene.appearance;
  for (const Camera& c : synthCameraPath(SynthSceneKind::Room, 3, kWidth, kHeight, 0.5)) {
    const FrameAlignment a = align(c, frameFrom(c, truth), truth);
    EXPECT_NE(a.status, AlignStatus::Failed) << a.why;
    EXPECT_LE(a.costAfter, a.costBefore);
    // The noise of a 160x120 frame and its model moves a right pose by 1.6-2.3 mm, 0.01-0.04 deg.
    EXPECT_LT(poseTranslation(c, a.camera), 0.003);
    EXPECT_LT(poseRotationDeg(c, a.camera), 0.05);
  }
}

TEST_F(PoseRefinement, AFrameWithNothingToAlignOnIsRefused) {
  // A uniform grey room without its lights' edges in view: no gradient fixes the pose.
  Appearance flat = room_->scene.appearance;
  std::fill(flat.albedo.rgb.begin(), flat.albedo.rgb.end(), 0.5f);
  Camera c = synthCameraPath(SynthSceneKind::Room, 1, kWidth, kHeight, 0.0).front();
  c.fx = c.fy = 4000;  // a narrow view of the middle of one surface
  c.cx = kWidth / 2.0f, c.cy = kHeight / 2.0f;
  const FrameAlignment a = align(moved(c, Vec3(1, 0, 0), 0.01, Vec3(0, 1, 0), 0.3), frameFrom(c, flat), flat);
  EXPECT_EQ(a.status, AlignStatus::Failed);
  EXPECT_NE(a.why.find("degrees of freedom"), std::string::npos) << a.why;
}

}  // namespace

namespace {

// The first global iteration of `stage` in a fit's metrics.jsonl (its lines every metrics_every).
int firstIterationOf(const std::filesystem::path& metrics, const std::string& stage) {
  std::ifstream in(metrics);
  std::string line;
  int first = -1;
  while (std::getline(in, line)) {
    const Json j = Json::parse(line);
    if (j["stage"] == stage) {
      first = j["iteration"].get<int>() - j["stage_iteration"].get<int>();
      break;
    }
  }
  return first;
}

}  // namespace

TEST(PoseRefinementFit, AnEstimatedPoseIsRefinedAndAResumedFitKeepsItsPoses) {
  namespace fs = std::filesystem;
  const fs::path dir = preparedCapture("pose_fit", room256("pose=1cm,0.3deg"), 256);
  FitConfig c = smallFitConfig();
  c.refinePoses = RefinePoses::Auto;  // on: the capture's poses are estimates
  runFit(dir / "work", c, false);
  const Json frames = readJson(dir / "work" / "result" / "frames.json");
  ASSERT_TRUE(frames.contains("poses"));
  ASSERT_EQ(frames["poses"]["rounds"].size(), 1u);  // one resolution: after the first albedo stage
  EXPECT_EQ(frames["poses"]["rounds"][0]["round"], "albedo@256");
  int aligned = 0;
  for (const Json& f : frames["poses"]["rounds"][0]["frames"]) aligned += f["status"] == "aligned";
  EXPECT_GT(aligned, 0);
  const Image whole = readImage(dir / "work" / "result" / "albedo.exr");

  // Stopped three iterations after the refinement, then resumed: the same poses, the same albedo.
  const int materials = firstIterationOf(dir / "work" / "metrics.jsonl", "materials");
  ASSERT_GT(materials, 0);
  fs::remove_all(dir / "work" / "result");
  FitConfig stopped = c;
  stopped.stopAfterIterations = materials + 3;
  EXPECT_TRUE(runFit(dir / "work", stopped, false).stopped);
  EXPECT_FALSE(runFit(dir / "work", c, true).stopped);
  EXPECT_EQ(readJson(dir / "work" / "result" / "frames.json")["poses"], frames["poses"]);
  EXPECT_EQ(readImage(dir / "work" / "result" / "albedo.exr").rgb, whole.rgb);
}

TEST(PoseRefinementFit, ExactPosesAreLeftAsTheyAre) {
  namespace fs = std::filesystem;
  const fs::path dir = preparedCapture("pose_fit_exact", room256(), 256);
  FitConfig c = smallFitConfig();
  c.refinePoses = RefinePoses::Auto;  // off: synth says its poses are exact
  c.albedoPasses = 8, c.materialIterations = 0;
  runFit(dir / "work", c, false);
  EXPECT_FALSE(readJson(dir / "work" / "result" / "frames.json").contains("poses"));
}
