#include "product/fit_checkpoint.h"

#include "core/error.h"
#include "scene/texel_map.h"

namespace relume {

void CheckpointIo::integer(const char* key, int& value, int64_t lo, int64_t hi) {
  if (out_)
    out_->meta[key] = value;
  else
    value = static_cast<int>(in_->metaInteger(key, lo, hi));
}

void CheckpointIo::number(const char* key, double& value) {
  if (out_)
    out_->meta[key] = value;
  else
    value = in_->meta.value(key, 0.0);
}

void CheckpointIo::boolean(const char* key, bool& value) {
  if (out_)
    out_->meta[key] = value;
  else
    value = in_->meta.value(key, false);
}

void CheckpointIo::json(const char* key, Json& value) {
  if (out_)
    out_->meta[key] = value;
  else
    value = in_->meta.value(key, Json::array());
}

void FitPosition::serialise(CheckpointIo& io, int stageCount) {
  io.integer("stage", stage, 0, stageCount);
  io.integer("iteration", iteration, 0, INT32_MAX);
  io.integer("global_iteration", globalIteration, 0, INT32_MAX);
  io.integer("resolution", resolution, 1, kMaxTextureResolution);
  io.boolean("emission_textures", emissionTextures);
  if (io.writing() || emissionTextures)
    io.integer("emission_texture_resolution", emissionTextureResolution, emissionTextures ? 1 : 0,
               kMaxTextureResolution);
  io.number("loss", loss);
}

namespace {
Json runOf(Json config) {
  config.erase("stop_after_iterations");
  return config;
}
}  // namespace

void writeRunHeader(Checkpoint& ck, const Json& config) {
  ck.meta["version"] = kFitCheckpointVersion;
  ck.meta["config"] = config;
}

void checkRunHeader(const Checkpoint& ck, const Json& config, const std::string& file) {
  if (ck.meta.value("version", 0) != kFitCheckpointVersion || runOf(ck.meta.value("config", Json())) != runOf(config))
    fail("{}: checkpoint was written with another config; rerun without --resume", file);
}

}  // namespace relume
