// 8/16-bit frames: the camera response, the clip thresholds a saturated or black code implies,
// and how the frame cache keeps them.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <fstream>

#include "capture/frame_image.h"
#include "capture/frame_store.h"
#include "core/error.h"
#include "io/image.h"

using namespace relume;
namespace fs = std::filesystem;

namespace {

fs::path testDir() {
  const fs::path d = fs::temp_directory_path() / "relume_ldr_frames_test";
  fs::create_directories(d);
  return d;
}

// A PNG holding exactly these codes (grey: the same code in every channel).
template <typename T>
fs::path writeCodes(const std::string& name, int w, int h, const std::vector<T>& grey) {
  const fs::path p = testDir() / name;
  std::vector<T> rgb;
  for (T v : grey) rgb.insert(rgb.end(), {v, v, v});
  auto out = OIIO::ImageOutput::create(p.string());
  const OIIO::TypeDesc type = sizeof(T) == 1 ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::UINT16;
  OIIO::ImageSpec spec(w, h, 3, type);
  EXPECT_TRUE(out->open(p.string(), spec) && out->write_image(type, rgb.data()) && out->close());
  return p;
}

Frame frameOf(const fs::path& image, int w, int h, float exposure) {
  Frame f;
  f.image = image;
  f.camera.width = w, f.camera.height = h;
  f.exposure = exposure;
  return f;
}

}  // namespace

TEST(Response, FormsAndErrors) {
  const fs::path dir = testDir();
  EXPECT_EQ(Response::parse("srgb", dir, "t").kind(), Response::Kind::Srgb);
  EXPECT_FLOAT_EQ(Response::parse("gamma:2.2", dir, "t").toLinear(0.5f, false), std::pow(0.5f, 2.2f));
  EXPECT_FLOAT_EQ(Response::parse("linear", dir, "t").toLinear(0.25f, false), 0.25f);
  // A table: linear values at evenly spaced codes, interpolated.
  const Response t = Response::fromJson(Json::parse(R"({"table": [0, 0.1, 1]})"), dir, "t");
  EXPECT_FLOAT_EQ(t.toLinear(0.25f, false), 0.05f);
  EXPECT_FLOAT_EQ(t.toLinear(0.75f, false), 0.55f);
  std::ofstream(dir / "curve.txt") << "# a calibration\n0 0.2\n0.5 1\n";
  EXPECT_FLOAT_EQ(Response::parse("table:curve.txt", dir, "t").toLinear(1.0f / 3.0f, false), 0.2f);
  // The default decodes sRGB unless the file says it is linear.
  EXPECT_FLOAT_EQ(Response().toLinear(0.5f, false), srgbToLinear(0.5f));
  EXPECT_FLOAT_EQ(Response().toLinear(0.5f, true), 0.5f);
  const auto message = [&](const std::string& spec) {
    try {
      (void)Response::fromJson(Json::parse(spec), dir, "capture.json: 'response'");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(R"({"table": [0, 0.5, 0.4, 1]})").find("not monotonic: entry 2"), std::string::npos);
  EXPECT_NE(message(R"({"table": [0, 0.5, 0.5]})").find("not monotonic"), std::string::npos);
  EXPECT_NE(message(R"({"table": [1]})").find("2 to"), std::string::npos);
  EXPECT_NE(message(R"({"gamma": 0})").find("gamma 0 must be in"), std::string::npos);
  EXPECT_NE(message(R"("log")").find("'log' is not one of"), std::string::npos);
  EXPECT_NE(message(R"("table:missing.txt")").find("missing.txt"), std::string::npos);
  EXPECT_NE(message(R"({"table": [0, 1], "gamma": 2})").find("capture.json: 'response'"), std::string::npos);
  std::ofstream(dir / "bad.txt") << "0 0.5 x\n";
  EXPECT_NE(message(R"("table:bad.txt")").find("line 1: 'x' is not a number"), std::string::npos);
}

// A saturated code bounds the radiance from below, a black one from above: the thresholds lie
// half a code inside the encoding's range, in exposure-corrected linear values.
TEST(LdrFrames, EightBitCodesGiveTheirThresholds) {
  const fs::path png = writeCodes<uint8_t>("codes8.png", 4, 1, {0, 1, 254, 255});
  const FrameImage f = loadFrame(frameOf(png, 4, 1, 2.0f));
  EXPECT_EQ(f.read.bits, 8);
  EXPECT_FLOAT_EQ(f.image.at(2, 0)[0], srgbToLinear(254.0f / 255.0f) / 2.0f);
  EXPECT_FLOAT_EQ(f.image.at(3, 0)[0], 0.5f);
  EXPECT_GT(f.clipHigh, f.image.at(2, 0)[0]);  // 254 is a value
  EXPECT_LE(f.clipHigh, f.image.at(3, 0)[0]);  // 255 only a bound
  EXPECT_LT(f.clipLow, f.image.at(1, 0)[0]);   // 1 is a value
  EXPECT_GE(f.clipLow, f.image.at(0, 0)[0]);   // 0 only a bound
  // A frame's own clip_high can only tighten its threshold.
  Frame tight = frameOf(png, 4, 1, 2.0f);
  tight.clipHigh = 0.3f;
  EXPECT_FLOAT_EQ(loadFrame(tight).clipHigh, 0.3f);
  tight.clipHigh = 5.0f;
  EXPECT_FLOAT_EQ(loadFrame(tight).clipHigh, f.clipHigh);
  // Another response moves values and thresholds alike.
  Frame gamma = frameOf(png, 4, 1, 1.0f);
  gamma.response = Response::gamma(2.0, "t");
  const FrameImage g = loadFrame(gamma);
  EXPECT_FLOAT_EQ(g.image.at(2, 0)[0], std::pow(254.0f / 255.0f, 2.0f));
  EXPECT_GT(g.clipHigh, g.image.at(2, 0)[0]);
  EXPECT_LE(g.clipHigh, g.image.at(3, 0)[0]);
}

// At 16 bits the top codes are closer than a half float's step: the threshold sits one step
// below the top, so the cache's rounding cannot turn a saturated pixel into a value.
TEST(LdrFrames, SixteenBitTopSurvivesTheHalfFloatCache) {
  const fs::path png = writeCodes<uint16_t>("codes16.png", 4, 2, {0, 30000, 65534, 65535, 65535, 65535, 65535, 65535});
  const Frame frame = frameOf(png, 4, 2, 3.0f);
  const FrameImage f = loadFrame(frame);
  EXPECT_EQ(f.read.bits, 16);
  EXPECT_LE(f.clipHigh, f.image.at(3, 0)[0]);
  const fs::path cache = testDir() / "frames16.bin";
  const auto stats = writeFrameStore(cache, {frame});
  const FrameStore store(cache);
  EXPECT_FLOAT_EQ(store.stats(0).clipHigh, f.clipHigh);
  EXPECT_EQ(store.stats(0).bits, 16u);
  EXPECT_GE(store.pixel(0, 3, 0)[0], store.stats(0).clipHigh);  // saturated after half rounding
  EXPECT_LT(store.pixel(0, 1, 0)[0], store.stats(0).clipHigh);
  EXPECT_FLOAT_EQ(stats[0].overexposed, 6.0f / 8.0f);
}

// A stored value that mixes saturated and unsaturated pixels bounds nothing: the frame cache
// masks such a block, and bilinear lookups across a saturation edge find no reference.
TEST(LdrFrames, MixedSaturationIsNeitherValueNorBound) {
  // 4 x 2: left half 128, right half 255.
  const fs::path png = writeCodes<uint8_t>("edge.png", 4, 2, {128, 128, 255, 255, 128, 128, 255, 255});
  const Frame frame = frameOf(png, 4, 2, 1.0f);
  const fs::path cache = testDir() / "edge.bin";
  writeFrameStore(cache, {frame});
  {
    const FrameStore store(cache);
    EXPECT_TRUE(store.bilinear(0, Vec2(1.0f, 1.0f)).has_value());   // both 128
    EXPECT_FALSE(store.bilinear(0, Vec2(2.0f, 1.0f)).has_value());  // 128 and 255
    const auto bright = store.bilinear(0, Vec2(3.0f, 1.0f));        // both 255: a bound
    ASSERT_TRUE(bright.has_value());
    EXPECT_GE((*bright)[0], store.stats(0).clipHigh);
  }
  // Downscaled by 2: the left 2 x 2 block mixes 128 and 255, the right one is all 255.
  const fs::path mixed = writeCodes<uint8_t>("mixed.png", 4, 2, {128, 255, 255, 255, 128, 128, 255, 255});
  writeFrameStore(cache, {frameOf(mixed, 4, 2, 1.0f)}, 2);
  const FrameStore store(cache);
  EXPECT_LT(store.pixel(0, 0, 0)[0], 0.0f);  // masked: 128 and 255 averaged
  EXPECT_GE(store.pixel(0, 1, 0)[0], store.stats(0).clipHigh);
}

TEST(LdrFrames, FloatFramesKeepTheirOwnThresholds) {
  Image img(2, 1);
  img.set(0, 0, Color::Constant(4.0f));
  writeExr(testDir() / "hdr.exr", img);
  Frame f = frameOf(testDir() / "hdr.exr", 2, 1, 1.0f);
  EXPECT_EQ(loadFrame(f).clipHigh, std::numeric_limits<float>::infinity());
  EXPECT_EQ(loadFrame(f).read.bits, 0);
  f.clipHigh = 3.0f;
  EXPECT_FLOAT_EQ(loadFrame(f).clipHigh, 3.0f);
}
