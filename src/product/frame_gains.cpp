#include "product/frame_gains.h"

#include <spdlog/spdlog.h>

#include <cmath>

#include "core/check.h"
#include "core/error.h"
#include "product/fit_checkpoint.h"

namespace relume {
namespace {

// Rays a frame's decayed sums must hold before its gain moves: below, one batch's noise would.
constexpr double kMinRays = 32;
// A gain outside this range is a broken frame, not a camera setting.
constexpr float kMinGain = 1e-3f, kMaxGain = 1e3f;

bool usableForGain(const BatchRay& ray, const Color& estimate) {
  return isFinite(estimate) && (ray.reference > ray.clip.low).all() && (ray.reference < ray.clip.high).all();
}

}  // namespace

FrameGainMode resolveFrameGains(FrameGainMode asked, const std::vector<Frame>& frames, const FrameStore& store,
                                std::span<const uint32_t> kept) {
  if (asked != FrameGainMode::Auto) return asked;
  for (uint32_t f : kept)
    if (store.stats(f).bits != 0 && !frames[f].exposureRecorded) return FrameGainMode::Rgb;
  return FrameGainMode::None;
}

FrameGains::FrameGains(FrameGainMode mode, size_t frameCount, std::vector<uint32_t> kept, int referenceFrame,
                       float memory)
    : mode_(mode),
      kept_(std::move(kept)),
      reference_(referenceFrame),
      memory_(memory),
      gain_(frameCount, Color::Ones()),
      sumReference_(3 * frameCount, 0.0),
      sumEstimate_(3 * frameCount, 0.0),
      rays_(frameCount, 0.0) {
  CHECK(mode != FrameGainMode::Auto);
  CHECK(memory >= 0 && memory < 1);
  if (reference_ >= 0 && std::find(kept_.begin(), kept_.end(), static_cast<uint32_t>(reference_)) == kept_.end())
    fail("fit: gain_reference_frame {} is not one of the {} frames prepare kept", reference_, kept_.size());
}

void FrameGains::start(const std::vector<Color>& initial) {
  if (!estimated()) return;
  CHECK(initial.size() == gain_.size());
  for (uint32_t f : kept_) {
    const Color g = initial[f].max(kMinGain).min(kMaxGain);
    gain_[f] = mode_ == FrameGainMode::Exposure ? Color::Constant(std::cbrt(g[0] * g[1] * g[2])) : g;
  }
  fixGauge();
}

void FrameGains::apply(std::span<BatchRay> rays, std::span<const uint32_t> frameOf) const {
  CHECK(rays.size() == frameOf.size());
  for (size_t j = 0; j < rays.size(); ++j) rays[j].gain = gain_[frameOf[j]];
}

void FrameGains::update(std::span<const BatchRay> rays, std::span<const uint32_t> frameOf,
                        std::span<const int> objectOf, std::span<const uint8_t> excluded,
                        std::span<const Color> estimates) {
  if (!estimated()) return;
  CHECK(rays.size() == frameOf.size() && rays.size() == estimates.size() && rays.size() == objectOf.size());
  for (double& s : sumReference_) s *= memory_;
  for (double& s : sumEstimate_) s *= memory_;
  for (double& n : rays_) n *= memory_;
  for (size_t j = 0; j < rays.size(); ++j) {
    const int object = objectOf[j];
    if (!usableForGain(rays[j], estimates[j]) ||
        (object >= 0 && static_cast<size_t>(object) < excluded.size() && excluded[static_cast<size_t>(object)]))
      continue;
    const size_t f = frameOf[j];
    for (int c = 0; c < 3; ++c) {
      sumReference_[3 * f + c] += rays[j].reference[c];
      sumEstimate_[3 * f + c] += estimates[j][c];
    }
    rays_[f] += 1;
  }
  for (uint32_t f : kept_) {
    if (rays_[f] < kMinRays) continue;
    const double* ref = &sumReference_[3 * f];
    const double* est = &sumEstimate_[3 * f];
    Color g = gain_[f];
    if (mode_ == FrameGainMode::Exposure) {
      const double e = est[0] + est[1] + est[2];
      if (e > 0) g = Color::Constant(static_cast<float>((ref[0] + ref[1] + ref[2]) / e));
    } else {
      for (int c = 0; c < 3; ++c)
        if (est[c] > 0) g[c] = static_cast<float>(ref[c] / est[c]);
    }
    gain_[f] = g.max(kMinGain).min(kMaxGain);
  }
  fixGauge();
}

void FrameGains::fixGauge() {
  Color scale;
  if (reference_ >= 0) {
    scale = gain_[static_cast<size_t>(reference_)];
  } else {
    Eigen::Array3d logSum = Eigen::Array3d::Zero();
    for (uint32_t f : kept_) logSum += gain_[f].cast<double>().log();
    scale = (logSum / static_cast<double>(std::max<size_t>(1, kept_.size()))).exp().cast<float>();
  }
  for (Color& g : gain_) g /= scale;
}

void FrameGains::serialise(CheckpointIo& io) {
  if (!io.optional("frame_gains.gain", estimated())) return;
  std::vector<float> g(3 * gain_.size());
  for (size_t f = 0; f < gain_.size(); ++f)
    for (int c = 0; c < 3; ++c) g[3 * f + c] = gain_[f][c];
  io.array("frame_gains.gain", g);
  for (size_t f = 0; f < gain_.size(); ++f) gain_[f] = Color(g[3 * f], g[3 * f + 1], g[3 * f + 2]);
  io.array("frame_gains.sum_reference", sumReference_);
  io.array("frame_gains.sum_estimate", sumEstimate_);
  io.array("frame_gains.rays", rays_);
}

Json FrameGains::toJson(const std::vector<Frame>& frames) const {
  Json j;
  j["mode"] = enumName(mode_);
  j["gauge"] = reference_ >= 0 ? fmt::format("frame {} has gain 1", reference_)
                               : std::string("geometric mean of the kept frames' gains is 1");
  Json list = Json::array();
  for (uint32_t f : kept_) {
    const Color& g = gain_[f];
    list.push_back({{"frame", f},
                    {"image", frames[f].image.filename().string()},
                    {"gain", {g[0], g[1], g[2]}},
                    {"rays", rays_[f]}});
  }
  j["frames"] = list;
  return j;
}

}  // namespace relume
