// Frames that repeat another frame's image: the same file (by canonical path, so
// images/../images/x.png is images/x.png) or the same bytes under another name.
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include "capture/transforms.h"

namespace relume {

struct DuplicateFrame {
  size_t frame;        // the repeat: skipped
  size_t original;     // the earlier frame with the same image and view: kept
  std::string reason;  // "duplicate of frame <original> (...)"
};

// Two views are the same when every camera number agrees to this relative tolerance (a pose
// written and read back in decimal differs by a few float ulps, about 1e-7).
inline constexpr double kSameViewTolerance = 1e-5;

// Every frame whose image an earlier frame already shows from the same view (pose, intrinsics,
// exposure, clip levels), in frame order: to be skipped, so that a repeated frame is neither
// weighted twice nor counted twice. The same image from two different views is a relume::Error
// naming the capture file and both frames: which view is right cannot be known.
std::vector<DuplicateFrame> findDuplicateFrames(const Capture& capture);

}  // namespace relume
