// Progress: the ETA's arithmetic, durations as text, and bars nested in a phase's bar.
#include <gtest/gtest.h>

#include <cmath>

#include <tbb/parallel_for.h>

#include "core/system.h"

using namespace relume;

TEST(Progress, EtaIsTheTimeSoFarPerUnitTimesTheUnitsLeft) {
  EXPECT_FALSE(etaSeconds(5.0, 0.0, 10.0).has_value());  // no pace before the first unit
  EXPECT_DOUBLE_EQ(*etaSeconds(5.0, 1.0, 10.0), 45.0);
  EXPECT_DOUBLE_EQ(*etaSeconds(30.0, 3.0, 4.0), 10.0);
  EXPECT_DOUBLE_EQ(*etaSeconds(2.0, 0.25, 1.0), 6.0);  // fractions of a unit count
  EXPECT_DOUBLE_EQ(*etaSeconds(8.0, 4.0, 4.0), 0.0);
  EXPECT_DOUBLE_EQ(*etaSeconds(8.0, 5.0, 4.0), 0.0);  // past the total: nothing left, never negative
}

TEST(Progress, DurationsReadAsSecondsMinutesHours) {
  EXPECT_EQ(formatDuration(0.4), "0s");
  EXPECT_EQ(formatDuration(42.4), "42s");
  EXPECT_EQ(formatDuration(185), "3m05s");
  EXPECT_EQ(formatDuration(3725), "1h02m");
  EXPECT_EQ(formatDuration(-3), "0s");
}

TEST(Progress, DurationsParseFromWhatAPersonTypes) {
  EXPECT_EQ(parseDuration("600"), 600.0);
  EXPECT_EQ(parseDuration("90s"), 90.0);
  EXPECT_EQ(parseDuration("10m"), 600.0);
  EXPECT_EQ(parseDuration("1.5h"), 5400.0);
  EXPECT_EQ(parseDuration("1h30m"), 5400.0);
  EXPECT_EQ(parseDuration("2m30s"), 150.0);
  for (const char* bad : {"", "m", "10x", "1h30", "-5", "1..5s", "10 m", "1e400", "h1"})
    EXPECT_FALSE(parseDuration(bad).has_value()) << bad;
}

TEST(Progress, ByteSizesParseFromWhatAPersonTypes) {
  const double gib = 1024.0 * 1024 * 1024;
  EXPECT_EQ(parseByteSize("2G"), 2 * gib);
  EXPECT_EQ(parseByteSize("2g"), 2 * gib);
  EXPECT_EQ(parseByteSize("2GiB"), 2 * gib);
  EXPECT_EQ(parseByteSize("2GB"), 2 * gib);
  EXPECT_EQ(parseByteSize("1.5G"), 1.5 * gib);
  EXPECT_EQ(parseByteSize("512M"), 512.0 * 1024 * 1024);
  EXPECT_EQ(parseByteSize("64k"), 65536.0);
  EXPECT_EQ(parseByteSize("1T"), 1024 * gib);
  EXPECT_EQ(parseByteSize("1000"), 1000.0);
  EXPECT_EQ(parseByteSize("1000B"), 1000.0);
  EXPECT_EQ(parseByteSize("4611686018427387904"), std::ldexp(1.0, 62));
  for (const char* bad : {"", "G", "2X", "2GG", "-1G", "2 G", "1..5G", "1e400", "2Gi", "5P", "2iB", "9999999999T"})
    EXPECT_FALSE(parseByteSize(bad).has_value()) << bad;
  EXPECT_EQ(formatBytes(200), "200 B");
  EXPECT_EQ(formatBytes(1.5 * gib), "1.50 GiB");
  EXPECT_EQ(formatBytes(512.0 * 1024 * 1024), "512 MiB");
  EXPECT_EQ(formatBytes(20.0 * 1024 * 1024), "20.0 MiB");
}

TEST(Progress, ABarInsideAnotherCarriesItThroughItsCurrentUnit) {
  Progress phase("phase", 4);
  phase.advance();
  EXPECT_DOUBLE_EQ(phase.fraction(), 0.25);
  {
    Progress frame("frame", 10);
    tbb::parallel_for(0, 5, [&](int) { frame.advance(); });  // workers advance the nested bar
    EXPECT_DOUBLE_EQ(frame.fraction(), 0.5);
    EXPECT_DOUBLE_EQ(phase.fraction(), 0.25 + 0.5 / 4);
    {
      Progress deeper("deeper", 2);
      deeper.advance();  // half of the frame's next unit: 5.5 of 10
      EXPECT_DOUBLE_EQ(frame.fraction(), 0.55);
      EXPECT_DOUBLE_EQ(phase.fraction(), 0.25 + 0.55 / 4);
    }
    EXPECT_DOUBLE_EQ(frame.fraction(), 0.5);  // the unit a finished bar carried is its outer bar's to count
  }
  EXPECT_DOUBLE_EQ(phase.fraction(), 0.25);
  phase.advance();
  EXPECT_DOUBLE_EQ(phase.fraction(), 0.5);
  Progress next("next frame", 2);  // a later bar nests in the phase again, not in the finished one
  next.advance();
  EXPECT_DOUBLE_EQ(phase.fraction(), 0.5 + 0.5 / 4);
}

TEST(Progress, FractionStopsAtOne) {
  Progress p("p", 2);
  p.advance(5);
  EXPECT_DOUBLE_EQ(p.fraction(), 1.0);
  Progress empty("empty", 0);  // a phase with nothing to do counts as one unit
  EXPECT_DOUBLE_EQ(empty.fraction(), 0.0);
}
