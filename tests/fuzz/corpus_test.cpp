// Replays the fuzzing corpus (seeds and every input that once crashed a reader) through the
// readers in the ordinary build: each file must be read or rejected with relume::Error.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "optim/checkpoint.h"
#include "product/confidence.h"
#include "product/light_decisions.h"
#include "product/time_budget.h"
#include "readers.h"

namespace fs = std::filesystem;

namespace {

const fs::path kCorpus = fs::path(RELUME_TEST_DATA) / "fuzz";

class Corpus : public testing::TestWithParam<std::string> {};

TEST_P(Corpus, EveryFileIsReadOrRejectedWithAnError) {
  const fs::path dir = kCorpus / GetParam();
  ASSERT_TRUE(fs::is_directory(dir)) << dir;
  size_t files = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    std::ifstream in(entry.path(), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(relume::fuzz::readBytes(GetParam(), reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
    ++files;
  }
  EXPECT_GE(files, 2u) << "corpus of " << GetParam() << " has no seeds";
}

// Test names allow only letters, digits and '_': colmap-text runs as Corpus.../colmap_text.
INSTANTIATE_TEST_SUITE_P(Readers, Corpus, testing::ValuesIn(relume::fuzz::readerNames()),
                         [](const testing::TestParamInfo<std::string>& p) {
                           std::string name = p.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(Corpus, EveryFolderHasAReader) {
  const std::vector<std::string> names = relume::fuzz::readerNames();
  for (const auto& entry : fs::directory_iterator(kCorpus)) {
    if (!entry.is_directory()) continue;
    EXPECT_NE(std::find(names.begin(), names.end(), entry.path().filename().string()), names.end()) << entry.path();
  }
}

// The checkpoint seed made by hand (scripts/fuzz_seeds.py --hand-made) reads through the fit's
// per-object records and the settled albedo's, so the fuzzer starts from an input that reaches them.
TEST(CheckpointSeed, TheRecordsSeedReadsToTheEnd) {
  const relume::Checkpoint c = relume::Checkpoint::read(kCorpus / "checkpoint" / "seed_records.bin");
  relume::CheckpointIo io = relume::CheckpointIo::reader(c);
  relume::ObjectRoles roles(2);
  ASSERT_NO_THROW(roles.serialise(io, "seed"));
  EXPECT_EQ(roles.roughnessAtLeast[1], 0.6f);
  EXPECT_EQ(roles.sharpBelow[1], 0.15f);
  relume::SettledAlbedo settled;
  ASSERT_NO_THROW(settled.serialise(io, c.bytes("albedo") / (3 * sizeof(float)), "seed"));
  EXPECT_TRUE(settled.beyondOneKnown);
  EXPECT_EQ(settled.beyondOne, std::vector<uint32_t>{1});
  std::vector<relume::Stage> stages(3, relume::Stage{"", {0}, 64, 2000});
  relume::TimeBudget budget(1.0, stages, std::vector<double>(3, 1.0));
  double elapsed = 0;
  ASSERT_NO_THROW(budget.serialise(io, elapsed, "seed"));
  budget.apply(stages);
  EXPECT_EQ(elapsed, 42.5);
  EXPECT_EQ(stages[1].iterations, 1000);
}

}  // namespace
