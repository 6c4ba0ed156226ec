#include "product/frame_poses.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "core/check.h"
#include "core/error.h"
#include "core/system.h"
#include "render/lights.h"

namespace relume {
FramePoses::FramePoses(const std::vector<Frame>& given) : dropped_(given.size(), 0) {
  for (const Frame& f : given) given_.push_back(f.camera);
}

void FramePoses::refine(Workspace& w, const Appearance& model, const Render& render, const FrameGains& gains,
                        const PoseAlignSettings& s, bool drop, const std::string& round) {
  Timer timer;
  const LightSampler lights(*w.scene, model);
  std::vector<FrameAlignment> result;
  for (uint32_t f : w.kept) {
    Camera camera = w.frames[f].camera;
    const AlignImage image = alignImageFromStore(*w.store, f, luminance(gains.gain(f)), s.width, camera);
    const AlignImage aim =
        renderedTarget(*w.scene, model, lights, targetGrid(camera), render.spp, render.seed + f, render.path);
    result.push_back(alignFrame(*w.scene, camera, image, aim, s));
  }
  Json entries = Json::array();
  std::vector<double> moved, turned;
  int aligned = 0, failed = 0;
  std::vector<uint32_t> kept;
  for (size_t i = 0; i < result.size(); ++i) {
    const uint32_t f = w.kept[i];
    const FrameAlignment& a = result[i];
    Json e = {{"frame", f},
              {"status", alignStatusName(a.status)},
              {"pixels", a.pixels},
              {"cost_before", a.costBefore},
              {"cost_after", a.costAfter},
              {"conditioning", a.conditioning}};
    if (!a.why.empty()) e["why"] = a.why;
    if (a.status == AlignStatus::Aligned) {
      moved.push_back(poseTranslation(w.frames[f].camera, a.camera));
      turned.push_back(poseRotationDeg(w.frames[f].camera, a.camera));
      e["moved_m"] = moved.back(), e["turned_deg"] = turned.back();
      w.frames[f].camera.rotation = a.camera.rotation;
      w.frames[f].camera.position = a.camera.position;
      ++aligned;
    }
    if (a.status == AlignStatus::Failed) {
      ++failed;
      spdlog::warn("fit: frame {} ({}) not aligned: {}{}", f, w.frames[f].image.filename().string(), a.why,
                   drop ? "; dropped (unaligned_frames: drop)" : "; kept at its pose");
    }
    if (a.status == AlignStatus::Failed && drop)
      dropped_[f] = 1;
    else
      kept.push_back(f);
    entries.push_back(std::move(e));
  }
  if (kept.empty()) fail("{}: pose refinement after {} could align no frame", w.dir.string(), round);
  w.kept = std::move(kept);
  rounds_.push_back(round);
  log_.push_back({{"round", round}, {"frames", entries}});
  spdlog::info(
      "fit: poses refined after {}: {} frames aligned (median step {:.2f} mm, {:.3f} deg), {} unchanged, {} failed, "
      "{:.1f} s",
      round, aligned, 1e3 * medianOf(moved), medianOf(turned), entries.size() - aligned - failed, failed,
      timer.seconds());
}

void FramePoses::serialise(CheckpointIo& io, Workspace& w) {
  if (!io.optional("poses.cameras", refined())) return;
  std::vector<float> cameras(12 * w.frames.size());
  if (io.writing())
    for (size_t f = 0; f < w.frames.size(); ++f) {
      const Camera& c = w.frames[f].camera;
      for (int i = 0; i < 9; ++i) cameras[12 * f + i] = c.rotation(i / 3, i % 3);
      for (int i = 0; i < 3; ++i) cameras[12 * f + 9 + i] = c.position[i];
    }
  io.array("poses.cameras", cameras);
  io.array("poses.dropped", dropped_);
  Json rounds = rounds_;
  io.json("pose_rounds", rounds);
  io.json("pose_log", log_);
  if (io.writing()) return;
  rounds_ = rounds.get<std::vector<std::string>>();
  for (size_t f = 0; f < w.frames.size(); ++f) {
    Camera& c = w.frames[f].camera;
    for (int i = 0; i < 9; ++i) c.rotation(i / 3, i % 3) = cameras[12 * f + i];
    for (int i = 0; i < 3; ++i) c.position[i] = cameras[12 * f + 9 + i];
  }
  std::erase_if(w.kept, [&](uint32_t f) { return dropped_[f] != 0; });
}

Json FramePoses::toJson(const std::vector<Frame>& frames) const {
  CHECK_EQ(frames.size(), given_.size());
  Json list = Json::array();
  for (size_t f = 0; f < frames.size(); ++f) {
    const Camera& c = frames[f].camera;
    Json rows = Json::array();
    const Mat3 gl = c.rotationToOpenGL();
    for (int i = 0; i < 3; ++i) rows.push_back({gl(i, 0), gl(i, 1), gl(i, 2), c.position[i]});
    rows.push_back({0, 0, 0, 1});
    list.push_back({{"frame", f},
                    {"image", frames[f].image.filename().string()},
                    {"dropped", dropped_[f] != 0},
                    {"moved_m", poseTranslation(given_[f], c)},
                    {"turned_deg", poseRotationDeg(given_[f], c)},
                    {"transform_matrix", rows}});
  }
  return {{"rounds", log_}, {"frames", list}};
}

}  // namespace relume
