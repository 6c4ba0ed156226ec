// The fit's frame poses: each kept frame's pose refined between stages (pose_refinement.h) and
// what became of it, checkpointed with the rest and written to result/frames.json.
#pragma once
#include <string>
#include <vector>

#include "product/fit_checkpoint.h"
#include "product/fit_workspace.h"
#include "product/frame_gains.h"
#include "product/pose_refinement.h"

namespace relume {

class FramePoses {
 public:
  // `given`: the capture's cameras as read (the corrections are measured from them).
  explicit FramePoses(const std::vector<Frame>& given);

  // How a frame's target is rendered (renderedTarget): frame f's render draws from seed + f.
  struct Render {
    int spp = 16;
    PathSettings path;
    uint64_t seed = 0;
  };
  // Aligns every kept frame of `w` with `model` rendered from its current pose (all from the poses
  // the round starts with), then moves the aligned ones in w.frames and, with `drop`, takes the
  // failed ones out of w.kept. `round` names the refinement in logs and the result.
  void refine(Workspace& w, const Appearance& model, const Render& render, const FrameGains& gains,
              const PoseAlignSettings& s, bool drop, const std::string& round);
  bool refined() const { return !rounds_.empty(); }
  // Restores w.frames' poses and w.kept from a checkpoint that holds them (or writes them).
  void serialise(CheckpointIo& io, Workspace& w);
  // Per frame: the correction from the given pose, and each round's status.
  Json toJson(const std::vector<Frame>& frames) const;

 private:
  std::vector<Camera> given_;
  std::vector<std::string> rounds_;
  Json log_ = Json::array();  // per round: per frame, the alignment
  std::vector<uint8_t> dropped_;
};

}  // namespace relume
