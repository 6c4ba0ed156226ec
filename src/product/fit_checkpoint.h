// The fit's checkpoint: every field is listed once, in a function that takes a CheckpointIo, and
// the same function writes it (CheckpointIo::writer) and reads it back (CheckpointIo::reader), so
// writing and resuming cannot disagree on what a checkpoint holds.
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/check.h"
#include "io/json.h"
#include "optim/checkpoint.h"

namespace relume {

// Version 7: the time budget's plan (6: refined poses; 5: the scale probes of lights seen only
// saturated; 4: frame gains; 3: light decisions and out-of-model objects).
inline constexpr int kFitCheckpointVersion = 7;

class CheckpointIo {
 public:
  static CheckpointIo writer(Checkpoint& ck) { return CheckpointIo(&ck, nullptr); }
  static CheckpointIo reader(const Checkpoint& ck) { return CheckpointIo(nullptr, &ck); }
  bool writing() const { return out_ != nullptr; }

  // A named array; when reading, `data` must already have the stored size.
  template <typename T>
  void array(const std::string& name, std::span<T> data) {
    transfer(name, data, false);
  }
  template <typename T>
  void array(const std::string& name, std::vector<T>& data) {
    transfer(name, std::span<T>(data), false);
  }
  // The same for an array that stays alive and unchanged until the checkpoint is written: a
  // writer refers to it instead of copying it (Checkpoint::putInPlace; the per-texel state).
  template <typename T>
  void arrayInPlace(const std::string& name, std::span<T> data) {
    transfer(name, data, true);
  }
  template <typename T>
  void arrayInPlace(const std::string& name, std::vector<T>& data) {
    transfer(name, std::span<T>(data), true);
  }
  // A one-entry array.
  template <typename T>
  void single(const std::string& name, T& value) {
    std::vector<T> v{value};
    array(name, v);
    value = v[0];
  }
  // Whether the optional arrays under `name` are there: writing, `present`; reading, whether the
  // checkpoint has `name`.
  bool optional(const std::string& name, bool present) const { return out_ ? present : in_->has(name); }

  // Header fields; an integer read back outside [lo, hi] is an error naming the file.
  void integer(const char* key, int& value, int64_t lo, int64_t hi);
  void number(const char* key, double& value);
  void boolean(const char* key, bool& value);
  void json(const char* key, Json& value);

 private:
  CheckpointIo(Checkpoint* out, const Checkpoint* in) : out_(out), in_(in) {}
  template <typename T>
  void transfer(const std::string& name, std::span<T> data, bool inPlace) {
    if (!out_)
      in_->get(name, data);
    else if (inPlace)
      out_->putInPlace(name, std::span<const T>(data));
    else
      out_->put(name, std::span<const T>(data));
  }
  Checkpoint* out_;
  const Checkpoint* in_;
};

// Where a fit stands: which stage and iteration continue, and the texture sizes to allocate
// before the parameters are read.
struct FitPosition {
  int stage = 0, iteration = 0, globalIteration = 0;
  int resolution = 0;  // the albedo's
  bool emissionTextures = false;
  int emissionTextureResolution = 0;  // 0 without emission textures
  double loss = 0;                    // the last iteration's

  void serialise(CheckpointIo& io, int stageCount);
};

// The header every fit checkpoint carries: its version and the run's config. A checkpoint
// continues the run its config describes; where to stop (stop_after_iterations) is not part of
// the run. Throws relume::Error naming `file` when `ck` belongs to another run.
void writeRunHeader(Checkpoint& ck, const Json& config);
void checkRunHeader(const Checkpoint& ck, const Json& config, const std::string& file);

}  // namespace relume
