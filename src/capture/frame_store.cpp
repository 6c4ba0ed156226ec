#include "capture/frame_store.h"

#include <Imath/half.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "core/error.h"
#include "capture/frame_image.h"
#include "core/prefetch.h"
#include "core/ranks.h"
#include "io/atomic_file.h"
#include "io/input_file.h"

namespace relume {
namespace {

constexpr char kMagic[8] = {'R', 'L', 'M', 'F', 'R', 'A', 'M', 'E'};
constexpr uint32_t kVersion = 3;

struct Header {
  char magic[8];
  uint32_t version;
  uint32_t frames;
};

struct DiskEntry {
  uint64_t offset;
  FrameStats stats;
};

}  // namespace

namespace {
// k x k box filter; a block containing a masked pixel is masked, and so is one whose mean falls
// under `clipHigh` in a channel where one of its pixels is saturated.
Image boxDownscale(const Image& img, int k, float clipHigh) {
  Image out(img.width / k, img.height / k);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      Color sum = Color::Zero(), brightest = Color::Zero();
      bool masked = false;
      for (int dy = 0; dy < k; ++dy)
        for (int dx = 0; dx < k; ++dx) {
          const Color c = img.at(x * k + dx, y * k + dy);
          masked = masked || c.minCoeff() < 0;
          sum += c;
          brightest = brightest.max(c);
        }
      const Color mean = sum / static_cast<float>(k * k);
      masked = masked || ((brightest >= clipHigh) && (mean < clipHigh)).any();
      out.set(x, y, masked ? Color::Constant(kMaskedPixel) : mean);
    }
  return out;
}
}  // namespace

namespace {
// Writes all of `bytes` at `offset` of the open file `fd`; fails naming `file`, the cache being
// written (a full disk).
void writeAt(int fd, const void* bytes, size_t size, uint64_t offset, const std::string& file) {
  const auto* p = static_cast<const uint8_t*>(bytes);
  while (size > 0) {
    const ssize_t n = ::pwrite(fd, p, size, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("{}: cannot write frame cache ({})", file, n < 0 ? std::strerror(errno) : "no space written");
    p += n, size -= static_cast<size_t>(n), offset += static_cast<uint64_t>(n);
  }
}

// Decodes frame `frame` into the file at its entry's offset and fills the entry's statistics.
void storeFrame(int fd, const std::string& file, const Frame& frame, int downscale, bool encodingClips,
                DiskEntry& e) {
  const FrameImage decoded = loadFrame(frame, encodingClips);
  const Image& full = decoded.image;
  e.stats.downscale = static_cast<uint32_t>(downscale);
  e.stats.clipLow = decoded.clipLow;
  e.stats.clipHigh = decoded.clipHigh;
  e.stats.bits = static_cast<uint32_t>(decoded.read.bits);
  size_t over = 0, under = 0;
  for (size_t p = 0; p < full.rgb.size() / 3; ++p) {
    const float* c = &full.rgb[3 * p];
    if (c[0] < 0) continue;  // masked
    over += std::max({c[0], c[1], c[2]}) >= decoded.clipHigh;
    under += std::max({c[0], c[1], c[2]}) <= decoded.clipLow;
  }
  const double n = std::max<double>(1, full.rgb.size() / 3);
  e.stats.overexposed = static_cast<float>(over / n);
  e.stats.underexposed = static_cast<float>(under / n);
  e.stats.masked = static_cast<float>(decoded.read.nonFinitePixels / n);
  const Image stored = downscale > 1 ? boxDownscale(full, downscale, decoded.clipHigh) : Image();
  const Image& px = downscale > 1 ? stored : full;
  // loadFrame refuses an image whose size is not its camera's, so the place planned is its own.
  CHECK(static_cast<uint32_t>(px.width) == e.stats.width && static_cast<uint32_t>(px.height) == e.stats.height);
  std::vector<Imath::half> halfs(px.rgb.size());
  for (size_t k = 0; k < px.rgb.size(); ++k) halfs[k] = Imath::half(std::min(px.rgb[k], 65504.0f));
  writeAt(fd, halfs.data(), halfs.size() * sizeof(Imath::half), e.offset, file);
}
}  // namespace

std::vector<FrameStats> writeFrameStore(const std::filesystem::path& path, const std::vector<Frame>& frames,
                                        int downscale, bool encodingClips, const std::function<void()>& progress) {
  if (downscale < 1 || downscale > 64) fail("{}: downscale must be 1..64, not {}", path.string(), downscale);
  Ranks& ranks = Ranks::world();
  // Every frame's place in the file follows from its camera's size, so each rank writes the frames
  // it decodes (frame i by rank i mod N) without waiting for the others'.
  std::vector<DiskEntry> entries(frames.size());
  uint64_t offset = sizeof(Header) + entries.size() * sizeof(DiskEntry);
  for (size_t i = 0; i < frames.size(); ++i) {
    DiskEntry& e = entries[i];
    e.offset = offset;
    e.stats.width = static_cast<uint32_t>(frames[i].camera.width / downscale);
    e.stats.height = static_cast<uint32_t>(frames[i].camera.height / downscale);
    offset += static_cast<uint64_t>(e.stats.width) * e.stats.height * 3 * sizeof(Imath::half);
  }
  const uint64_t fileBytes = offset;
  // Errors name the cache, not its temporary.
  const std::string file = path.string();
  // This rank's frames into the temporary `tmp` (sized already), then every rank's entries to every
  // rank.
  auto storeOwnFrames = [&](const std::string& tmp) {
    const int fd = ::open(tmp.c_str(), O_WRONLY);
    if (fd < 0) fail("{}: cannot open frame cache for writing ({})", file, std::strerror(errno));
    try {
      for (size_t i = 0; i < frames.size(); ++i) {
        if (!ranks.ownsChunk(i)) continue;
        storeFrame(fd, file, frames[i], downscale, encodingClips, entries[i]);
        if (progress) progress();
      }
    } catch (...) {
      ::close(fd);
      throw;
    }
    if (::close(fd) != 0) fail("{}: cannot write frame cache ({})", file, std::strerror(errno));
    ranks.shareChunks(entries, 1);
  };
  if (ranks.root()) {
    writeAtomically(path, [&](const std::filesystem::path& tmpPath) {
      // Absolute: the ranks may run in other working directories.
      const std::string tmp = std::filesystem::absolute(tmpPath).string();
      const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0666);  // less the umask, as ofstream
      if (fd < 0) fail("{}: cannot create frame cache ({})", file, std::strerror(errno));
      const bool sized = ::ftruncate(fd, static_cast<off_t>(fileBytes)) == 0;
      const int sizeError = errno;
      if (::close(fd) != 0 || !sized)
        fail("{}: cannot make room for the frame cache ({})", file, std::strerror(sized ? errno : sizeError));
      ranks.rootString(tmp);  // the other ranks write their frames into the same temporary
      storeOwnFrames(tmp);
      Header h{};
      std::memcpy(h.magic, kMagic, 8);
      h.version = kVersion;
      h.frames = static_cast<uint32_t>(frames.size());
      const int index = ::open(tmp.c_str(), O_WRONLY);
      if (index < 0) fail("{}: cannot open frame cache for writing ({})", file, std::strerror(errno));
      try {
        writeAt(index, &h, sizeof h, 0, file);
        writeAt(index, entries.data(), entries.size() * sizeof(DiskEntry), sizeof h, file);
      } catch (...) {
        ::close(index);
        throw;
      }
      if (::close(index) != 0) fail("{}: cannot write frame cache ({})", file, std::strerror(errno));
    });
  } else {
    storeOwnFrames(ranks.rootString(""));
  }
  ranks.allTrue(true);  // every rank goes on once the root has put the file in place
  std::vector<FrameStats> stats;
  for (const DiskEntry& e : entries) stats.push_back(e.stats);
  return stats;
}

FrameStore::FrameStore(const std::filesystem::path& path) {
  const std::string file = path.string();
  requireRegularFile(path, "a relume frame cache");
  const int fd = ::open(file.c_str(), O_RDONLY);
  if (fd < 0) fail("{}: cannot open frame cache", file);
  struct stat st {};
  if (fstat(fd, &st) != 0 || st.st_size < static_cast<off_t>(sizeof(Header))) {
    ::close(fd);
    fail("{}: frame cache is truncated", file);
  }
  size_ = static_cast<size_t>(st.st_size);
  void* p = mmap(nullptr, size_, PROT_READ, MAP_SHARED, fd, 0);
  ::close(fd);
  if (p == MAP_FAILED) fail("{}: cannot map frame cache", file);
  data_ = static_cast<const uint8_t*>(p);
  Header h;
  std::memcpy(&h, data_, sizeof(h));
  auto bad = [&](const std::string& why) {
    munmap(const_cast<uint8_t*>(data_), size_);
    data_ = nullptr;
    fail("{}: {}", file, why);
  };
  if (std::memcmp(h.magic, kMagic, 8) != 0 || h.version != kVersion)
    bad("not a relume frame cache (or another version)");
  if (sizeof(Header) + static_cast<uint64_t>(h.frames) * sizeof(DiskEntry) > size_)
    bad("frame cache index is truncated");
  index_.resize(h.frames);
  for (uint32_t i = 0; i < h.frames; ++i) {
    DiskEntry e;
    std::memcpy(&e, data_ + sizeof(Header) + i * sizeof(DiskEntry), sizeof(e));
    const FrameStats& s = e.stats;
    if (s.width > 65536 || s.height > 65536 || s.downscale < 1 || s.downscale > 64)
      bad(fmt::format("frame {}: size {}x{} / downscale {} out of range (65536 per side, downscale 1..64)", i, s.width,
                      s.height, s.downscale));
    for (const float fraction : {s.overexposed, s.underexposed, s.masked})
      if (!(fraction >= 0 && fraction <= 1))
        bad(fmt::format("frame {}: exposure statistic {} is not in [0, 1]", i, fraction));
    if (!(s.clipLow >= 0 && s.clipHigh > s.clipLow) || (s.bits != 0 && s.bits != 8 && s.bits != 16))
      bad(fmt::format("frame {}: clip thresholds [{}, {}] or encoding {} bits out of range", i, s.clipLow, s.clipHigh,
                      s.bits));
    // Written as a difference so a huge offset cannot wrap around.
    const uint64_t bytes = static_cast<uint64_t>(s.width) * s.height * 3 * sizeof(Imath::half);
    if (e.offset > size_ || bytes > size_ - e.offset) bad(fmt::format("frame {} lies outside the file", i));
    index_[i] = {e.offset, e.stats};
  }
}

FrameStore::~FrameStore() {
  if (data_) munmap(const_cast<uint8_t*>(data_), size_);
}

Color FrameStore::pixel(size_t frame, int x, int y) const {
  const Entry& e = index_[frame];
  Imath::half h[3];
  std::memcpy(h, data_ + e.offset + (static_cast<size_t>(y) * e.stats.width + x) * 3 * sizeof(Imath::half), sizeof(h));
  return {float(h[0]), float(h[1]), float(h[2])};
}

std::optional<FrameStore::StoredPixel> FrameStore::pixelAt(size_t frame, const Vec2& px) const {
  const Entry& e = index_[frame];
  const int ds = static_cast<int>(e.stats.downscale);
  const float xf = std::floor(px.x() / ds), yf = std::floor(px.y() / ds);
  if (!(xf >= 0 && yf >= 0 && xf < e.stats.width && yf < e.stats.height)) return std::nullopt;
  const int x = static_cast<int>(xf), y = static_cast<int>(yf);
  const Color c = pixel(frame, x, y);
  if (c.minCoeff() < 0) return std::nullopt;
  return StoredPixel{c, Vec2(static_cast<float>(x * ds), static_cast<float>(y * ds)), static_cast<float>(ds)};
}

void FrameStore::prefetch(size_t frame, const Vec2& px) const {
  const Entry& e = index_[frame];
  const float inv = 1.0f / static_cast<float>(e.stats.downscale);
  // The 2 x 2 block from bilinear's first pixel holds pixelAt's pixel too.
  const float xf = std::floor(px.x() * inv - 0.5f), yf = std::floor(px.y() * inv - 0.5f);
  const float maxX = static_cast<float>(e.stats.width) - 2, maxY = static_cast<float>(e.stats.height) - 2;
  if (!(maxX >= 0 && maxY >= 0)) return;
  const auto x = static_cast<size_t>(std::clamp(xf, 0.0f, maxX)), y = static_cast<size_t>(std::clamp(yf, 0.0f, maxY));
  constexpr size_t kPixelBytes = 3 * sizeof(Imath::half);
  for (size_t row = y; row < y + 2; ++row)
    prefetchBytes(data_ + e.offset + (row * e.stats.width + x) * kPixelBytes, 2 * kPixelBytes);
}

std::optional<Color> FrameStore::bilinear(size_t frame, const Vec2& px) const {
  const Entry& e = index_[frame];
  const float inv = 1.0f / static_cast<float>(e.stats.downscale);
  const float x = px.x() * inv - 0.5f, y = px.y() * inv - 0.5f;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= static_cast<int>(e.stats.width) || y0 + 1 >= static_cast<int>(e.stats.height))
    return std::nullopt;
  const float dx = x - x0, dy = y - y0;
  Color sum = Color::Zero();
  Eigen::Array3i saturated = Eigen::Array3i::Zero();
  const float w[4] = {(1 - dx) * (1 - dy), dx * (1 - dy), (1 - dx) * dy, dx * dy};
  for (int k = 0; k < 4; ++k) {
    const Color c = pixel(frame, x0 + (k & 1), y0 + (k >> 1));
    if (c.minCoeff() < 0) return std::nullopt;
    saturated += (c >= e.stats.clipHigh).cast<int>();
    sum += w[k] * c;
  }
  if (((saturated > 0) && (saturated < 4)).any()) return std::nullopt;
  return sum;
}

}  // namespace relume
