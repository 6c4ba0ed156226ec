// findDuplicateFrames: one image (by canonical path or by bytes) from one view is a duplicate to
// skip; from two views, an error naming both frames.
#include "capture/duplicate_frames.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <string>

#include "core/error.h"
#include "io/image.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

class DuplicateFramesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("relume_duplicate_frames_unit_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "images");
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A 4x4 image whose pixels are all `value`, at images/NAME.
  fs::path image(const std::string& name, float value) {
    Image img(4, 4);
    for (float& v : img.rgb) v = value;
    writeExr(dir_ / "images" / name, img);
    return dir_ / "images" / name;
  }
  Frame frame(const fs::path& file, float x = 0) {
    Frame f;
    f.camera.width = f.camera.height = 4, f.camera.fx = f.camera.fy = 4, f.camera.cx = f.camera.cy = 2;
    f.camera.position = Vec3(x, 0, 0);
    f.image = file;
    return f;
  }
  Capture capture(std::vector<Frame> frames) { return {dir_ / "transforms.json", {}, std::move(frames)}; }

  fs::path dir_;
};

}  // namespace

TEST_F(DuplicateFramesTest, DistinctImagesAreNotDuplicates) {
  // Same size, different bytes: hashed and told apart.
  const Capture c = capture({frame(image("a.exr", 0.1f)), frame(image("b.exr", 0.2f)), frame(image("c.exr", 0.3f))});
  EXPECT_TRUE(findDuplicateFrames(c).empty());
}

TEST_F(DuplicateFramesTest, TheSameFrameTwiceIsOneDuplicate) {
  const fs::path a = image("a.exr", 0.1f);
  const std::vector<DuplicateFrame> d = findDuplicateFrames(capture({frame(a), frame(image("b.exr", 0.2f)), frame(a)}));
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].frame, 2u);
  EXPECT_EQ(d[0].original, 0u);
  EXPECT_EQ(d[0].reason.rfind("duplicate of frame 0 (same image file", 0), 0u) << d[0].reason;
}

TEST_F(DuplicateFramesTest, PathsAreComparedCanonically) {
  const fs::path a = image("a.exr", 0.1f);
  fs::create_symlink(a, dir_ / "link.exr");
  const std::vector<DuplicateFrame> d = findDuplicateFrames(
      capture({frame(a), frame(dir_ / "images" / ".." / "images" / "a.exr"), frame(dir_ / "link.exr")}));
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].frame, 1u);
  EXPECT_EQ(d[1].frame, 2u);
  EXPECT_EQ(d[1].original, 0u);
}

TEST_F(DuplicateFramesTest, IdenticalBytesUnderTwoNamesAreOneImage) {
  const fs::path a = image("a.exr", 0.1f);
  fs::copy_file(a, dir_ / "images" / "copy.exr");
  // The copy's own repeat follows the copy to the original.
  const std::vector<DuplicateFrame> d = findDuplicateFrames(
      capture({frame(a), frame(dir_ / "images" / "copy.exr"), frame(dir_ / "images" / "copy.exr")}));
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0].original, 0u);
  EXPECT_EQ(d[1].original, 0u);
  EXPECT_NE(d[0].reason.find("same bytes"), std::string::npos) << d[0].reason;
}

TEST_F(DuplicateFramesTest, OneImageFromTwoViewsIsAnErrorNamingBothFrames) {
  const fs::path a = image("a.exr", 0.1f);
  try {
    findDuplicateFrames(capture({frame(a), frame(image("b.exr", 0.2f)), frame(a, 0.5f)}));
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("frame 0 and frame 2"), std::string::npos) << what;
    EXPECT_NE(what.find("position"), std::string::npos) << what;
    EXPECT_NE(what.find("transforms.json"), std::string::npos) << what;
  }
}

TEST_F(DuplicateFramesTest, ATinyPoseDifferenceIsTheSameView) {
  const fs::path a = image("a.exr", 0.1f);
  EXPECT_EQ(findDuplicateFrames(capture({frame(a), frame(a, 1e-7f)})).size(), 1u);
  Frame brighter = frame(a);
  brighter.exposure = 2;
  EXPECT_THROW(findDuplicateFrames(capture({frame(a), brighter})), Error);  // another exposure: another view
}

TEST_F(DuplicateFramesTest, AMissingImageIsLeftToItsReader) {
  EXPECT_TRUE(findDuplicateFrames(capture({frame(dir_ / "none.exr"), frame(image("a.exr", 0.1f))})).empty());
}
