#include "io/image.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <memory>
#include <optional>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/input_file.h"

namespace relume {

float srgbToLinear(float v) { return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f); }
float linearToSrgb(float v) { return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f; }

size_t countNonFinitePixels(const Image& image) {
  size_t n = 0;
  for (size_t i = 0; i + 2 < image.rgb.size(); i += 3)
    n += !(std::isfinite(image.rgb[i]) && std::isfinite(image.rgb[i + 1]) && std::isfinite(image.rgb[i + 2]));
  return n;
}

namespace {
Image readImageAs(const std::filesystem::path& path, ImageReadStats* stats, bool decode) {
  const std::string file = path.string();
  requireRegularFile(path, "an image file");
  auto in = OIIO::ImageInput::open(file);
  if (!in) fail("{}: cannot read image: {}", file, OIIO::geterror());
  const OIIO::ImageSpec& spec = in->spec();
  // A header of a few bytes may claim any size: bound what gets allocated before reading.
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.width > 65536 || spec.height > 65536 ||
      static_cast<int64_t>(spec.width) * spec.height > kMaxImagePixels)
    fail("{}: image size {}x{} ({} channels) out of range (positive, at most 65536 per side and {} pixels)", file,
         spec.width, spec.height, spec.nchannels, kMaxImagePixels);
  // RGB, or the first channel expanded to grey; further channels (alpha, AOVs) are never read.
  const int nc = spec.nchannels >= 3 ? 3 : 1;
  // Not zero-filled: a corrupt file whose header claims 8192 x 8192 fails without touching 800 MB.
  const auto raw = std::make_unique_for_overwrite<float[]>(static_cast<size_t>(spec.width) * spec.height * nc);
  if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::FLOAT, raw.get()))
    fail("{}: corrupt image data: {}", file, in->geterror());
  const bool isInteger =
      spec.format.basetype == OIIO::TypeDesc::UINT8 || spec.format.basetype == OIIO::TypeDesc::UINT16;
  const std::string colorSpace = spec.get_string_attribute("oiio:ColorSpace");
  const bool fileSaysLinear = isInteger && (colorSpace == "Linear" || colorSpace == "linear");
  const bool decodeSrgb = decode && isInteger && !fileSaysLinear;
  if (stats) {
    stats->bits = !isInteger ? 0 : spec.format.basetype == OIIO::TypeDesc::UINT8 ? 8 : 16;
    stats->fileSaysLinear = fileSaysLinear;
  }
  Image img(spec.width, spec.height);
  size_t bad = 0;
  for (size_t i = 0; i < static_cast<size_t>(spec.width) * spec.height; ++i) {
    for (int c = 0; c < 3; ++c) {
      float v = raw[i * nc + (nc == 3 ? c : 0)];
      if (decodeSrgb) v = srgbToLinear(v);
      img.rgb[3 * i + c] = v;
    }
    if (!std::isfinite(img.rgb[3 * i]) || !std::isfinite(img.rgb[3 * i + 1]) || !std::isfinite(img.rgb[3 * i + 2])) {
      img.rgb[3 * i] = img.rgb[3 * i + 1] = img.rgb[3 * i + 2] = 0.0f;
      ++bad;
      if (stats) stats->nonFiniteIndex.push_back(i);
    }
  }
  if (stats) stats->nonFinitePixels = bad;
  return img;
}
}  // namespace

Image readImage(const std::filesystem::path& path, ImageReadStats* stats) { return readImageAs(path, stats, true); }
Image readImageCodes(const std::filesystem::path& path, ImageReadStats* stats) {
  return readImageAs(path, stats, false);
}

namespace {
// Writes to `file`, or into `memory` when given (OIIO's I/O proxy; the file name picks the format).
void writeOiioTo(const std::filesystem::path& file, int w, int h, OIIO::TypeDesc storage, OIIO::TypeDesc memoryType,
                 const void* pixels, std::vector<uint8_t>* memory = nullptr) {
  auto out = OIIO::ImageOutput::create(file.string());
  if (!out) fail("{}: cannot create image writer: {}", file.string(), OIIO::geterror());
  std::optional<OIIO::Filesystem::IOVecOutput> proxy;
  if (memory) out->set_ioproxy(&proxy.emplace(*memory));
  OIIO::ImageSpec spec(w, h, 3, storage);
  // OIIO stamps EXRs with the wall-clock time (capDate) unless told one: an empty one keeps equal
  // pixels in equal bytes, whenever they are written.
  spec.attribute("DateTime", "");
  if (storage == OIIO::TypeDesc::FLOAT) spec.attribute("compression", "zip");
  if (!out->open(file.string(), spec) || !out->write_image(memoryType, pixels) || !out->close())
    fail("{}: cannot write image: {}", file.string(), out->geterror());
}

void writeOiio(const std::filesystem::path& path, int w, int h, OIIO::TypeDesc storage, OIIO::TypeDesc memory,
               const void* pixels) {
  writeAtomically(path, [&](const std::filesystem::path& tmp) { writeOiioTo(tmp, w, h, storage, memory, pixels); });
}

std::vector<uint16_t> srgb16(const Image& image) {
  std::vector<uint16_t> v(image.rgb.size());
  for (size_t i = 0; i < v.size(); ++i)
    v[i] = static_cast<uint16_t>(
        std::lround(std::clamp(linearToSrgb(std::max(0.0f, image.rgb[i])), 0.0f, 1.0f) * 65535.0f));
  return v;
}

std::vector<uint8_t> srgb8(const Image& image, float exposure) {
  std::vector<uint8_t> bytes(image.rgb.size());
  for (size_t i = 0; i < bytes.size(); ++i) {
    const float v = std::clamp(linearToSrgb(std::max(0.0f, image.rgb[i] * exposure)), 0.0f, 1.0f);
    bytes[i] = static_cast<uint8_t>(std::lround(v * 255.0f));
  }
  return bytes;
}

void writeSrgbPngTo(const std::filesystem::path& file, const Image& image, int bits, std::vector<uint8_t>* memory) {
  if (bits != 8 && bits != 16) fail("{}: PNG bit depth must be 8 or 16, not {}", file.string(), bits);
  if (bits == 8) {
    const auto v = srgb8(image, 1.0f);
    writeOiioTo(file, image.width, image.height, OIIO::TypeDesc::UINT8, OIIO::TypeDesc::UINT8, v.data(), memory);
  } else {
    const auto v = srgb16(image);
    writeOiioTo(file, image.width, image.height, OIIO::TypeDesc::UINT16, OIIO::TypeDesc::UINT16, v.data(), memory);
  }
}
}  // namespace

void writeExr(const std::filesystem::path& path, const Image& image) {
  writeOiio(path, image.width, image.height, OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::FLOAT, image.rgb.data());
}

void writePng(const std::filesystem::path& path, const Image& image, float exposure) {
  const auto bytes = srgb8(image, exposure);
  writeOiio(path, image.width, image.height, OIIO::TypeDesc::UINT8, OIIO::TypeDesc::UINT8, bytes.data());
}

void writeSrgbPng(const std::filesystem::path& path, const Image& image, int bits) {
  writeAtomically(path, [&](const std::filesystem::path& tmp) { writeSrgbPngTo(tmp, image, bits, nullptr); });
}

std::vector<uint8_t> encodeSrgbPng(const Image& image, int bits) {
  std::vector<uint8_t> bytes;
  writeSrgbPngTo("memory.png", image, bits, &bytes);
  return bytes;
}

}  // namespace relume
