// Numeric command-line options are range-checked before anything runs (NaN included): runs the
// relume binary next to tests/ in the build tree.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace fs = std::filesystem;

TEST(Cli, NumericOptionsAreRangeChecked) {
  const fs::path relume = fs::read_symlink("/proc/self/exe").parent_path().parent_path() / "relume";
  ASSERT_TRUE(fs::exists(relume)) << relume;
  const fs::path log = fs::temp_directory_path() / "relume_cli_ranges.log";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"render --scene /dev/null --cameras /dev/null --out /tmp/relume_cli_x --spp -3", "--spp: -3 is not in [1, 1048576]"},
      {"synth --out /tmp/relume_cli_x --spp 0", "--spp: 0 is not in [1, 1048576]"},
      {"synth --out /tmp/relume_cli_x --width 4", "--width: 4 is not in [8, 65536]"},
      {"prepare /tmp --out /tmp/relume_cli_x --tile 0", "--tile: 0 is not in [1, 4096]"},
      {"prepare /tmp --out /tmp/relume_cli_x --gutter-res 0", "--gutter-res: 0 is not in [1, 65536]"},
      {"prepare /tmp --out /tmp/relume_cli_x --max-overexposed nan", "--max-overexposed: nan is not in [0, 1]"},
      {"prepare /tmp --out /tmp/relume_cli_x --downscale 0", "--downscale: 0 is not in [1, 256]"},
      {"gradcheck --emission-scale 1e38", "--emission-scale: 1e38 is not in"},
      {"gradcheck --eps nan", "--eps: nan is not in"},
      {"gradcheck --batches 1", "--batches: 1 is not in [2, 1048576]"},
      {"gradcheck --clip-high nan", "--clip-high: nan is not in"},
      {"profile --rays 0", "--rays: 0 is not in [1, 67108864]"},
      {"profile --scatter-res -1", "--scatter-res: -1 is not in [1, 32768]"},
  };
  for (const auto& [args, expected] : cases) {
    const int rc = std::system((relume.string() + " " + args + " > " + log.string() + " 2>&1").c_str());
    std::stringstream out;
    out << std::ifstream(log).rdbuf();
    EXPECT_NE(rc, 0) << args;
    EXPECT_NE(out.str().find(expected), std::string::npos) << args << ": " << out.str();
  }
}
