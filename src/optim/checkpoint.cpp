#include "optim/checkpoint.h"

#include <fstream>
#include <limits>

#include "core/error.h"
#include "core/kill_point.h"
#include "io/atomic_file.h"
#include "io/input_file.h"

namespace relume {

namespace {
constexpr char kMagic[8] = {'R', 'L', 'M', 'C', 'K', 'P', '0', '1'};
}

std::span<const char> Checkpoint::find(const std::string& name) const {
  if (const auto it = arrays_.find(name); it != arrays_.end()) return it->second;
  if (const auto it = views_.find(name); it != views_.end()) return it->second;
  return {};
}

size_t Checkpoint::bytes(const std::string& name) const { return find(name).size(); }

void Checkpoint::copyOut(const std::string& name, void* out, size_t bytes) const {
  if (!has(name)) fail("{}: checkpoint has no array '{}'", source_.string(), name);
  const std::span<const char> data = find(name);
  if (data.size() != bytes)
    fail("{}: checkpoint array '{}' has {} bytes, expected {} (was it written for another work folder?)",
         source_.string(), name, data.size(), bytes);
  if (bytes) std::memcpy(out, data.data(), bytes);
}

void Checkpoint::write(const std::filesystem::path& path) const {
  // Copied and in-place arrays in one order, by name.
  std::map<std::string, std::span<const char>> all(views_.begin(), views_.end());
  for (const auto& [name, data] : arrays_) all[name] = data;
  writeAtomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    Json header = meta;
    Json index = Json::array();
    for (const auto& [name, data] : all) index.push_back({name, data.size()});
    const std::string text = Json{{"meta", header}, {"arrays", index}}.dump();
    const uint64_t length = text.size();
    out.write(kMagic, sizeof(kMagic));
    out.write(reinterpret_cast<const char*>(&length), sizeof(length));
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    size_t written = 0;
    for (const auto& [name, data] : all) {
      if (written++ == all.size() / 2) {
        out.flush();
        killPoint("checkpoint-half");
      }
      out.write(data.data(), static_cast<std::streamsize>(data.size()));
    }
    if (!out) fail("{}: could not write the checkpoint", path.string());
  });
}

Checkpoint Checkpoint::read(const std::filesystem::path& path) {
  requireRegularFile(path, "a relume checkpoint");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail("{}: cannot open checkpoint", path.string());
  in.seekg(0, std::ios::end);
  const uint64_t size = static_cast<uint64_t>(in.tellg());
  in.seekg(0);
  char magic[8] = {};
  uint64_t length = 0;
  in.read(magic, sizeof(magic));
  in.read(reinterpret_cast<char*>(&length), sizeof(length));
  if (!in || std::memcmp(magic, kMagic, sizeof(kMagic)) != 0) fail("{}: not a relume checkpoint", path.string());
  if (length > size - 16) fail("{}: checkpoint header is truncated", path.string());
  std::string text(length, '\0');
  in.read(text.data(), static_cast<std::streamsize>(length));
  Checkpoint c;
  c.source_ = path;
  const Json j = withJsonErrors(path, [&] { return Json::parse(text); });
  uint64_t offset = 16 + length;
  withJsonErrors(path, [&] {
    c.meta = j.at("meta");
    for (const Json& entry : j.at("arrays")) {
      const std::string name = entry.at(0).get<std::string>();
      const uint64_t n =
          static_cast<uint64_t>(jsonInteger(entry.at(1), 0, std::numeric_limits<int64_t>::max(), path.string(), name));
      if (n > size - offset) fail("{}: checkpoint array '{}' is truncated", path.string(), name);
      std::vector<char>& b = c.arrays_[name];
      b.resize(n);
      in.read(b.data(), static_cast<std::streamsize>(n));
      offset += n;
    }
    return 0;
  });
  if (!in || offset != size) fail("{}: checkpoint is truncated or has trailing bytes", path.string());
  return c;
}

int64_t Checkpoint::metaInteger(const char* key, int64_t lo, int64_t hi) const {
  if (!meta.is_object() || !meta.contains(key)) fail("{}: checkpoint header has no '{}'", source_.string(), key);
  return jsonInteger(meta.at(key), lo, hi, source_.string(), key);
}

}  // namespace relume
