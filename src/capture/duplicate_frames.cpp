#include "capture/duplicate_frames.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>

#include "core/error.h"

namespace relume {
namespace fs = std::filesystem;

namespace {

// Where a frame's image is, symlinks and ".." resolved; a path that cannot be resolved (a missing
// file: its reader reports it later) is compared as written, without "." and "..".
fs::path resolvedImage(const fs::path& image) {
  std::error_code ec;
  fs::path p = fs::canonical(image, ec);
  if (ec) p = image.lexically_normal();
  return p;
}

// Only files of equal size can hold the same bytes, and a file whose size cannot be read (its
// reader reports why) matches nothing.
std::optional<uintmax_t> sizeOf(const fs::path& file) {
  std::error_code ec;
  const uintmax_t size = fs::file_size(file, ec);
  return ec ? std::nullopt : std::optional<uintmax_t>(size);
}

// FNV-1a over the first 1 MiB: it tells almost every two different images of one size apart at the
// cost of one read of their headers; equal hashes are confirmed byte by byte (sameBytes).
constexpr std::streamsize kHashedBytes = 1 << 20;
uint64_t prefixHash(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::vector<char> buffer(kHashedBytes);
  in.read(buffer.data(), kHashedBytes);
  uint64_t h = 14695981039346656037ull;
  for (std::streamsize i = 0; i < in.gcount(); ++i) h = (h ^ static_cast<unsigned char>(buffer[i])) * 1099511628211ull;
  return h;
}

bool sameBytes(const fs::path& a, const fs::path& b) {
  std::ifstream ia(a, std::ios::binary), ib(b, std::ios::binary);
  if (!ia || !ib) return false;
  std::vector<char> ba(kHashedBytes), bb(kHashedBytes);
  while (ia && ib) {
    ia.read(ba.data(), kHashedBytes);
    ib.read(bb.data(), kHashedBytes);
    if (ia.gcount() != ib.gcount() || !std::equal(ba.begin(), ba.begin() + ia.gcount(), bb.begin())) return false;
  }
  return !ia && !ib;  // both at their end together
}

bool near(double a, double b) {
  return std::abs(a - b) <= kSameViewTolerance * std::max({1.0, std::abs(a), std::abs(b)});
}

// What differs between two frames' views, or "" when they are the same view.
std::string viewDifference(const Frame& a, const Frame& b) {
  const Camera &ca = a.camera, &cb = b.camera;
  if (ca.width != cb.width || ca.height != cb.height) return "image size";
  if (!near(ca.fx, cb.fx) || !near(ca.fy, cb.fy) || !near(ca.cx, cb.cx) || !near(ca.cy, cb.cy)) return "intrinsics";
  const Distortion &da = ca.distortion, &db = cb.distortion;
  if (!near(da.k1, db.k1) || !near(da.k2, db.k2) || !near(da.p1, db.p1) || !near(da.p2, db.p2) || !near(da.k3, db.k3))
    return "distortion";
  for (int k = 0; k < 3; ++k)
    if (!near(ca.position[k], cb.position[k])) return "position";
  for (int k = 0; k < 9; ++k)
    if (!near(ca.rotation(k), cb.rotation(k))) return "rotation";
  if (!near(a.exposure, b.exposure)) return "exposure";
  if (!near(a.clipLow, b.clipLow) || !(near(a.clipHigh, b.clipHigh) || a.clipHigh == b.clipHigh)) return "clip levels";
  return "";
}

// For every frame, the first frame showing the same image and how they were matched ("" for itself).
struct SameImage {
  std::vector<size_t> first;
  std::vector<std::string> how;
};

// Frames naming one file (resolved): each follows the first of them.
SameImage matchFiles(const std::vector<fs::path>& resolved) {
  SameImage m{std::vector<size_t>(resolved.size()), std::vector<std::string>(resolved.size())};
  std::map<fs::path, size_t> firstOf;
  for (size_t i = 0; i < resolved.size(); ++i) {
    const auto [it, isNew] = firstOf.emplace(resolved[i], i);
    m.first[i] = it->second;
    if (!isNew) m.how[i] = "same image file";
  }
  return m;
}

// Distinct files holding the same bytes: the frames of the later file follow the earliest frame
// of the first. Only files sharing a size are hashed, and only equal hashes compared.
void matchBytes(const std::vector<Frame>& frames, const std::vector<fs::path>& resolved, SameImage& m) {
  std::map<uintmax_t, std::vector<size_t>> bySize;  // file size -> the first frame of each file
  for (size_t i = 0; i < frames.size(); ++i)
    if (m.first[i] == i)
      if (const auto size = sizeOf(resolved[i])) bySize[*size].push_back(i);
  for (const auto& [size, files] : bySize) {
    if (files.size() < 2) continue;
    std::map<uint64_t, std::vector<size_t>> byHash;  // -> the first frames of distinct contents
    for (size_t i : files) {
      std::vector<size_t>& same = byHash[prefixHash(resolved[i])];
      const auto original =
          std::find_if(same.begin(), same.end(), [&](size_t j) { return sameBytes(resolved[j], resolved[i]); });
      if (original == same.end()) {
        same.push_back(i);
        continue;
      }
      for (size_t k = i; k < frames.size(); ++k)  // frame i's file, wherever it is named again
        if (m.first[k] == i) m.first[k] = *original, m.how[k] = "same bytes as " + frames[*original].image.string();
    }
  }
}

}  // namespace

std::vector<DuplicateFrame> findDuplicateFrames(const Capture& capture) {
  std::vector<fs::path> resolved;
  for (const Frame& f : capture.frames) resolved.push_back(resolvedImage(f.image));
  SameImage same = matchFiles(resolved);
  matchBytes(capture.frames, resolved, same);
  std::vector<DuplicateFrame> duplicates;
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    const size_t j = same.first[i];
    if (j == i) continue;
    const std::string difference = viewDifference(capture.frames[j], capture.frames[i]);
    if (!difference.empty())
      fail("{}: frame {} and frame {} show the same image {} ({}) from different views ({} differs); fix or remove one",
           capture.file.string(), j, i, capture.frames[i].image.string(), same.how[i], difference);
    duplicates.push_back({i, j, fmt::format("duplicate of frame {} ({}, same view)", j, same.how[i])});
  }
  return duplicates;
}

}  // namespace relume
