// `prepare` skips a frame that repeats another's image and view (counted once, as "duplicate", in
// prepare.json) and refuses one image given two different views.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>

#include "core/error.h"
#include "io/json.h"
#include "product/prepare.h"
#include "scenes/synth.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// A 3-frame 16x16 Cornell box capture in a fresh folder DIR/capture; `edit` changes its
// transforms.json (a JSON object with 'frames') before it is prepared.
fs::path captureWith(const std::string& name, const std::function<void(Json&, const fs::path&)>& edit) {
  const fs::path dir = fs::temp_directory_path() / ("relume_duplicate_frames_" + name);
  fs::remove_all(dir);
  SynthCaptureOptions so;
  so.kind = SynthSceneKind::Cornell;
  so.out = dir / "capture";
  so.frames = 3, so.testFrames = 1, so.width = so.height = 16, so.spp = 1, so.testSpp = 1, so.atlasResolution = 64;
  writeSynthCapture(so);
  Json transforms = readJson(so.out / "transforms.json");
  edit(transforms, so.out);
  writeJson(so.out / "transforms.json", transforms);
  return dir;
}

Json prepared(const fs::path& dir) {
  PrepareOptions po;
  po.resolutions = {64};
  po.atlas.gutterResolution = 64;
  prepareCapture(dir / "capture", dir / "work", po);
  return readJson(dir / "work" / "prepare.json")["phases"]["frames"];
}

// The duplicate (the last frame) is dropped once, as a duplicate, and every other frame is kept.
void expectOneDuplicateSkipped(const Json& frames) {
  EXPECT_EQ(frames["frames"].get<int>(), 4);
  EXPECT_EQ(frames["kept"], Json({0, 1, 2})) << frames.dump();
  ASSERT_EQ(frames["dropped"].size(), 1u) << frames.dump();
  EXPECT_EQ(frames["dropped"][0]["frame"].get<int>(), 3);
  EXPECT_NE(frames["dropped"][0]["reason"].get<std::string>().find("frame 1"), std::string::npos) << frames.dump();
  EXPECT_EQ(frames["dropped_by_reason"], Json({{"duplicate", 1}})) << frames.dump();
}

}  // namespace

TEST(DuplicateFrames, SameFrameListedTwiceIsSkippedOnce) {
  const fs::path dir =
      captureWith("listed_twice", [](Json& t, const fs::path&) { t["frames"].push_back(t["frames"][1]); });
  expectOneDuplicateSkipped(prepared(dir));
  fs::remove_all(dir);
}

// images/../images/x.exr is the same file as images/x.exr.
TEST(DuplicateFrames, SameFileByCanonicalPathIsSkipped) {
  const fs::path dir = captureWith("canonical", [](Json& t, const fs::path&) {
    Json copy = t["frames"][1];
    copy["file_path"] = "images/../images/" + fs::path(copy["file_path"].get<std::string>()).filename().string();
    t["frames"].push_back(copy);
  });
  expectOneDuplicateSkipped(prepared(dir));
  fs::remove_all(dir);
}

// A copy of an image under another name is the same image (same bytes).
TEST(DuplicateFrames, SameBytesUnderAnotherNameAreSkipped) {
  const fs::path dir = captureWith("same_bytes", [](Json& t, const fs::path& capture) {
    Json copy = t["frames"][1];
    fs::copy_file(capture / copy["file_path"].get<std::string>(), capture / "images" / "copy.exr");
    copy["file_path"] = "images/copy.exr";
    t["frames"].push_back(copy);
  });
  expectOneDuplicateSkipped(prepared(dir));
  fs::remove_all(dir);
}

// One image, two poses: which one is right cannot be known.
TEST(DuplicateFrames, SameFileWithTwoPosesIsAnError) {
  const fs::path dir = captureWith("two_poses", [](Json& t, const fs::path&) {
    Json copy = t["frames"][1];
    copy["transform_matrix"][0][3] = copy["transform_matrix"][0][3].get<double>() + 0.1;
    t["frames"].push_back(copy);
  });
  try {
    prepared(dir);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("frame 1"), std::string::npos) << what;
    EXPECT_NE(what.find("frame 3"), std::string::npos) << what;
    EXPECT_NE(what.find("transforms.json"), std::string::npos) << what;
  }
  fs::remove_all(dir);
}
