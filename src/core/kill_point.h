// Deterministic interruptions, for the tests that prove a `kill -9` anywhere survivable. With
// RELUME_KILL_AT="<point>:<n>" in the environment, the n-th pass (counting from 1) of this process
// through killPoint("<point>") sends the process SIGKILL, as `kill -9` would at that moment.
// Without the variable a point does nothing. The points:
//   atomic-write     a temporary of writeAtomically written in full, not yet renamed over its target
//   checkpoint-half  a checkpoint's temporary on disk up to its header and half of its arrays
//   result-half      WORK/result.partial/ holding the scene and the albedo, not yet materials.json
//   result-staged    WORK/result.partial/ complete, the previous WORK/result/ removed, not renamed yet
#pragma once
#include <string_view>

namespace relume {

// Throws an input error naming RELUME_KILL_AT if it is set but not "<known point>:<n >= 1>".
void killPoint(std::string_view point);

}  // namespace relume
