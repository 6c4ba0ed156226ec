// Checkpoint file: a JSON header (what the writer needs to resume: stage, iteration, settings)
// followed by named binary arrays (parameter groups, Adam moments and step counts, averages).
// Written atomically; the reader checks the magic, every length and the total size, and names
// the file in every error.
#pragma once
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <span>
#include <string>
#include <vector>

#include "io/json.h"

namespace relume {

class Checkpoint {
 public:
  Json meta = Json::object();

  template <typename T>
  void put(const std::string& name, std::span<const T> data) {
    views_.erase(name);
    std::vector<char>& b = arrays_[name];
    b.resize(data.size_bytes());
    if (!data.empty()) std::memcpy(b.data(), data.data(), data.size_bytes());
  }
  // Array `name` written from `data` itself rather than a copy: `data` must stay alive and
  // unchanged until write(). The per-texel state of a 4096^2 fit is GiBs, which a copy doubles.
  template <typename T>
  void putInPlace(const std::string& name, std::span<const T> data) {
    arrays_.erase(name);
    views_[name] = std::span<const char>(reinterpret_cast<const char*>(data.data()), data.size_bytes());
  }
  template <typename T>
  void put(const std::string& name, const std::vector<T>& data) {
    put(name, std::span<const T>(data));
  }
  bool has(const std::string& name) const { return arrays_.count(name) != 0 || views_.count(name) != 0; }
  // Copies array `name` into `out`, which must have exactly its size (throws relume::Error otherwise).
  template <typename T>
  void get(const std::string& name, std::span<T> out) const {
    copyOut(name, out.data(), out.size_bytes());
  }
  template <typename T>
  void get(const std::string& name, std::vector<T>& out) const {
    get(name, std::span<T>(out));
  }
  size_t bytes(const std::string& name) const;
  // Header field `key`, an integer in [lo, hi] (throws relume::Error naming the file otherwise).
  int64_t metaInteger(const char* key, int64_t lo, int64_t hi) const;

  void write(const std::filesystem::path& path) const;
  static Checkpoint read(const std::filesystem::path& path);

 private:
  void copyOut(const std::string& name, void* out, size_t bytes) const;
  std::span<const char> find(const std::string& name) const;  // empty data() when absent
  std::map<std::string, std::vector<char>> arrays_;
  std::map<std::string, std::span<const char>> views_;  // putInPlace's
  std::filesystem::path source_;
};

}  // namespace relume
