// Per-frame gains estimated with the reconstruction. A camera that exposes automatically or
// balances white per shot records gain x radiance with a gain nobody wrote down; the fit then
// predicts a frame's pixel as its gain times the rendered radiance (BatchRay::gain).
//
// The gains start from prepare's (the frames' agreement on diffuse texels, solved exactly). With
// gain_refine, the fit also updates them: a frame's pixels are linear in its gain, as a texel's
// are in its albedo, so each iteration updates it in closed form: the ratio of the frame's reference sum to its
// (gain-free) estimate sum over the rays whose reference is neither clipped nor masked, both sums decayed over the last
// iterations. The ratio estimator is unbiased by the estimates' path-tracing noise (a least- squares fit, sum(I x) /
// sum(x^2), is pulled down by it). Gains and radiance trade one scale, so the gauge is fixed: the gains' geometric mean
// over the kept frames is 1, or one frame's is 1.
#pragma once
#include <array>
#include <span>
#include <string_view>
#include <vector>

#include "capture/frame_store.h"
#include "capture/transforms.h"
#include "core/enum_names.h"
#include "io/json.h"
#include "sampling/batch.h"

namespace relume {

class CheckpointIo;

// auto: rgb when some kept frame is integer-encoded (a camera's JPEG or PNG) without a recorded
// exposure, none otherwise. exposure: one scalar gain per frame; rgb: one per channel.
enum class FrameGainMode { Auto, None, Exposure, Rgb };
template <>
struct EnumNames<FrameGainMode> {
  static constexpr std::array<std::pair<FrameGainMode, std::string_view>, 4> values{
      {{FrameGainMode::Auto, "auto"},
       {FrameGainMode::None, "none"},
       {FrameGainMode::Exposure, "exposure"},
       {FrameGainMode::Rgb, "rgb"}}};
};

// What `asked` means for these frames (auto resolved; the others as they are).
FrameGainMode resolveFrameGains(FrameGainMode asked, const std::vector<Frame>& frames, const FrameStore& store,
                                std::span<const uint32_t> kept);

class FrameGains {
 public:
  // `mode` resolved (not Auto); `referenceFrame` < 0: geometric-mean gauge; `memory`: the factor
  // the sums decay by per iteration.
  FrameGains(FrameGainMode mode, size_t frameCount, std::vector<uint32_t> kept, int referenceFrame, float memory);

  FrameGainMode mode() const { return mode_; }
  bool estimated() const { return mode_ != FrameGainMode::None; }
  const Color& gain(uint32_t frame) const { return gain_[frame]; }
  // The gains prepare found in the frames' agreement (frame_gains.json, photometric_consistency.h),
  // per channel; in exposure mode each frame's channels' geometric mean. The gauge is then fixed.
  void start(const std::vector<Color>& initial);
  // Sets every ray's gain to its frame's (frameOf[j]: ray j's frame).
  void apply(std::span<BatchRay> rays, std::span<const uint32_t> frameOf) const;
  // Adds the batch (each ray's gain-free radiance estimate) to the decayed sums, then gives every
  // frame with evidence its closed-form gain and fixes the gauge. Rays aimed at objects whose
  // radiance is a fitted unknown of its own (`excluded[object]`: light sources, whose emission
  // shares the gains' scale, and what the model cannot hold) are left out: in a frame that sees a
  // lamp its pixels would outweigh all others.
  void update(std::span<const BatchRay> rays, std::span<const uint32_t> frameOf, std::span<const int> objectOf,
              std::span<const uint8_t> excluded, std::span<const Color> estimates);
  void serialise(CheckpointIo& io);
  // result/frames.json: the mode, the gauge and each frame's gain and evidence.
  Json toJson(const std::vector<Frame>& frames) const;

 private:
  void fixGauge();

  FrameGainMode mode_;
  std::vector<uint32_t> kept_;
  int reference_;
  float memory_;
  std::vector<Color> gain_;
  // Per frame: decayed sums of reference and estimate per channel, and of rays.
  std::vector<double> sumReference_, sumEstimate_, rays_;
};

}  // namespace relume
