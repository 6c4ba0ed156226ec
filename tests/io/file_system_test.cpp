// io/file_system.h: a path that cannot be examined is an error naming it and the reason, never a
// missing path and never a std::filesystem_error.
#include "io/file_system.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "core/error.h"
#include "io/input_file.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

// A folder holding `loop`, a symlink to itself.
fs::path folderWithLoop() {
  const fs::path dir = fs::temp_directory_path() / ("relume_file_system_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::create_symlink("loop", dir / "loop");
  return dir;
}

template <typename Call>
void expectErrorNaming(const fs::path& path, Call&& call) {
  try {
    call();
    ADD_FAILURE() << path << ": no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(path.string() + ": ", 0), 0u) << what;
    EXPECT_NE(what.find("symbolic links"), std::string::npos) << what;
  }
}

}  // namespace

TEST(FileSystem, ASymlinkLoopIsAnErrorNotAMissingPath) {
  const fs::path dir = folderWithLoop(), loop = dir / "loop";
  expectErrorNaming(loop, [&] { pathExists(loop); });
  expectErrorNaming(loop, [&] { isDirectory(loop); });
  expectErrorNaming(loop, [&] { requireDirectory(loop, "a folder"); });
  expectErrorNaming(loop, [&] { fileSize(loop); });
  expectErrorNaming(loop, [&] { canonicalPath(loop); });
  expectErrorNaming(loop / "x", [&] { createDirectories(loop / "x"); });
  expectErrorNaming(loop, [&] { requireRegularFile(loop, "a JSON file"); });
  fs::remove_all(dir);
}

TEST(FileSystem, MissingPathsAreNotErrors) {
  const fs::path dir = folderWithLoop();
  EXPECT_FALSE(pathExists(dir / "none"));
  EXPECT_FALSE(isDirectory(dir / "none"));
  EXPECT_TRUE(pathExists(dir) && isDirectory(dir));
  removeFile(dir / "none");
  fs::remove_all(dir);
}
