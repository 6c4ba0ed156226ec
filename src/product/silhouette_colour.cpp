#include "product/silhouette_colour.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/check.h"

namespace relume {
namespace {

constexpr int kFar = std::numeric_limits<int>::max() / 2;

// One pixel's measurement: the log of the light's colour, its weight (inverse variance), and the
// jackknife unit it belongs to (its frame and tile of kTile x kTile stored pixels, whose
// backgrounds overlap).
struct ColourSample {
  Eigen::Array3d logColour;
  double weight;
  uint64_t unit;
};
constexpr int kTile = 8;
constexpr int kCoverage = 8;
constexpr uint64_t kNoUnit = ~uint64_t{0};
constexpr double kOutlierMads = 4;

// A rectangle of stored pixels, [x0, x1) x [y0, y1).
struct Region {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  size_t size() const { return static_cast<size_t>(std::max(0, width())) * static_cast<size_t>(std::max(0, height())); }
};

// The stored pixels around where the light's triangles (`vertices`, three per triangle) project,
// `margin` pixels wider, clipped to the image (empty when they miss it). Triangles are cut at a
// plane just in front of the camera, so that a light partly behind it spans only what lies in front.
Region regionAround(const Camera& cam, const std::vector<Vec3>& vertices, int downscale, int storedWidth,
                    int storedHeight, int margin) {
  constexpr float kNear = 1e-3f;
  float lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  const auto add = [&](const Vec3& v) {
    if (const auto p = cam.project(v); p && p->allFinite())
      for (int k = 0; k < 2; ++k) lo[k] = std::min(lo[k], (*p)[k]), hi[k] = std::max(hi[k], (*p)[k]);
  };
  const auto depth = [&](const Vec3& v) { return (cam.rotation.transpose() * (v - cam.position)).z(); };
  for (size_t t = 0; t + 2 < vertices.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const Vec3 &a = vertices[t + k], &b = vertices[t + (k + 1) % 3];
      const float za = depth(a), zb = depth(b);
      if (za >= kNear) add(a);
      if ((za - kNear) * (zb - kNear) < 0) add(a + (b - a) * ((kNear - za) / (zb - za)));
    }
  if (!(lo[0] <= hi[0] && lo[1] <= hi[1])) return {};
  // Clamped as floats first: a point just in front of the camera projects far outside the image.
  const auto stored = [&](float v, int size) {
    return static_cast<int>(std::floor(std::clamp(v / static_cast<float>(downscale), -1.0f, size + 1.0f)));
  };
  return {std::max(0, stored(lo[0], storedWidth) - margin), std::max(0, stored(lo[1], storedHeight) - margin),
          std::min(storedWidth, stored(hi[0], storedWidth) + margin + 1),
          std::min(storedHeight, stored(hi[1], storedHeight) + margin + 1)};
}

// Chessboard distance of every pixel to the nearest one where `inside` holds (kFar: none).
std::vector<int> chessboardDistance(const std::vector<uint8_t>& inside, int width, int height) {
  std::vector<int> d(inside.size());
  for (size_t i = 0; i < inside.size(); ++i) d[i] = inside[i] ? 0 : kFar;
  const auto at = [&](int x, int y) { return d[static_cast<size_t>(y) * width + x]; };
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      int& v = d[static_cast<size_t>(y) * width + x];
      if (x > 0) v = std::min(v, at(x - 1, y) + 1);
      if (y > 0) {
        v = std::min(v, at(x, y - 1) + 1);
        if (x > 0) v = std::min(v, at(x - 1, y - 1) + 1);
        if (x + 1 < width) v = std::min(v, at(x + 1, y - 1) + 1);
      }
    }
  for (int y = height - 1; y >= 0; --y)
    for (int x = width - 1; x >= 0; --x) {
      int& v = d[static_cast<size_t>(y) * width + x];
      if (x + 1 < width) v = std::min(v, at(x + 1, y) + 1);
      if (y + 1 < height) {
        v = std::min(v, at(x, y + 1) + 1);
        if (x + 1 < width) v = std::min(v, at(x + 1, y + 1) + 1);
        if (x > 0) v = std::min(v, at(x - 1, y + 1) + 1);
      }
    }
  return d;
}

// The colour samples of `light` in one frame.
std::vector<ColourSample> frameSamples(const Workspace& w, uint32_t frame, const Color& gain, int light,
                                       const std::vector<Vec3>& vertices, double emission,
                                       const std::vector<uint8_t>& emitter, const SilhouetteColourSettings& s) {
  const FrameStore& store = *w.store;
  const FrameStats& stats = store.stats(frame);
  const Camera& cam = w.frames[frame].camera;
  const int ds = static_cast<int>(stats.downscale);
  // Pixels within `inner` of the light may hold some of it through the filter; those from `near`
  // to `far` hold none and are the background.
  const int inner = static_cast<int>(std::ceil(cam.filter.radius() / static_cast<float>(ds))) + 1;
  const int near = inner + 2, far = inner + 4;
  if (!std::isfinite(stats.clipHigh)) return {};  // a float frame clips nothing: no light in it is seen only saturated
  const Region r = regionAround(cam, vertices, ds, static_cast<int>(stats.width), static_cast<int>(stats.height), far);
  if (r.size() == 0 || r.size() > s.maxPixelsPerFrame) return {};
  std::vector<int> label(r.size(), -1);
  tbb::parallel_for(0, r.height(), [&](int row) {
    for (int col = 0; col < r.width(); ++col) {
      const Vec2 centre((static_cast<float>(r.x0 + col) + 0.5f) * static_cast<float>(ds),
                        (static_cast<float>(r.y0 + row) + 0.5f) * static_cast<float>(ds));
      const auto dir = cam.rayDirection(centre);
      if (!dir) continue;
      if (const auto hit = w.scene->intersect(cam.position, *dir))
        label[static_cast<size_t>(row) * r.width() + col] = hit->object;
    }
  });
  std::vector<uint8_t> isLight(r.size());
  for (size_t i = 0; i < r.size(); ++i) isLight[i] = label[i] == light;
  if (std::find(isLight.begin(), isLight.end(), 1) == isLight.end()) return {};
  const std::vector<int> dist = chessboardDistance(isLight, r.width(), r.height());

  const float clipHigh = stats.clipHigh, clipLow = stats.clipLow;
  const auto value = [&](int col, int row) -> std::optional<Color> {
    const Color v = store.pixel(frame, r.x0 + col, r.y0 + row);
    if (!v.allFinite() || v.minCoeff() < 0 || (v >= clipHigh).any()) return std::nullopt;
    return v;
  };
  // The clip level in radiance: the light clips in this frame, so its emission is at least that.
  const double clipLevel = luminance(Color(Color::Constant(std::isfinite(clipHigh) ? clipHigh : 0.0f) / gain));
  const double lumE = std::max(emission, clipLevel);
  // The share of the pixel's filter the light covers, from kCoverage^2 stratified rays: a pixel
  // beside the light that holds none of it (f = 0) may still differ from the ring around it.
  const auto coverage = [&](int col, int row) {
    int hits = 0;
    for (int k = 0; k < kCoverage * kCoverage; ++k) {
      const auto offset = [&](int i) {
        const float u = (static_cast<float>(i) + 0.5f) / kCoverage * static_cast<float>(ds);
        return std::floor(u) + cam.filter.sample(u - std::floor(u));
      };
      const Vec2 at(static_cast<float>((r.x0 + col) * ds) + offset(k % kCoverage),
                    static_cast<float>((r.y0 + row) * ds) + offset(k / kCoverage));
      const auto dir = cam.rayDirection(at);
      if (!dir) continue;
      const auto hit = w.scene->intersect(cam.position, *dir);
      hits += hit && hit->object == light;
    }
    return static_cast<double>(hits) / (kCoverage * kCoverage);
  };
  // The 8-bit encoding's step near the clip level, in radiance: the noise floor of a pixel.
  const double quantum = clipLevel / 512;
  std::vector<ColourSample> out;
  std::vector<float> channel[4];
  for (int row = 0; row < r.height(); ++row)
    for (int col = 0; col < r.width(); ++col) {
      if (dist[static_cast<size_t>(row) * r.width() + col] > inner) continue;
      const auto I = value(col, row);
      // Well below the clip level in every channel: a pixel near it is kept only where its noise
      // happened to fall low, which would bias the colour against its brightest channel.
      if (!I || (*I <= clipLow).any() || (*I > static_cast<float>(s.maxShareOfClip) * clipHigh).any()) continue;
      for (auto& c : channel) c.clear();
      // Another light near the pixel may have some of its light in it, and no background tells how much.
      bool besideOther = false;
      for (int y = std::max(0, row - far); y <= std::min(r.height() - 1, row + far); ++y)
        for (int x = std::max(0, col - far); x <= std::min(r.width() - 1, col + far); ++x) {
          const size_t i = static_cast<size_t>(y) * r.width() + x;
          besideOther |= label[i] >= 0 && label[i] != light && emitter[label[i]];
          if (dist[i] < near || dist[i] > far || label[i] < 0 || emitter[label[i]]) continue;
          if (const auto b = value(x, y)) {
            for (int c = 0; c < 3; ++c) channel[c].push_back((*b)[c]);
            channel[3].push_back(luminance(Color(*b / gain)));
          }
        }
      if (channel[0].size() < 3 || besideOther || coverage(col, row) == 0) continue;
      Color B;
      for (int c = 0; c < 3; ++c) B[c] = medianOf(channel[c]);
      const Color radiance = *I / gain, background = B / gain, x = radiance - background;
      const double lx = luminance(x), lb = luminance(background);
      if (x.minCoeff() <= 0) continue;
      if (lx < s.minExcess * clipLevel) continue;
      if (lx < s.minOverBackground * lb || lumE <= lb) continue;
      const double f = lx / (lumE - lb);
      if (f > 1) continue;  // brighter than the light itself: not this light's outline
      // The background's spread around its median (MAD, as a standard deviation) is what an error
      // in B amounts to; the colour's error goes as that over lum(x).
      for (float& v : channel[3]) v = std::abs(v - static_cast<float>(lb));
      const double spread = 1.4826 * medianOf(channel[3]);
      const double noiseSquared = spread * spread + quantum * quantum;  // and the 8-bit step
      // An excess within a few of those of 0 is the background's noise, whose colour is the
      // background's (a path-traced frame at 4 samples per pixel: no sample of an outline pixel
      // can hit a light 10x the clip and leave it unclipped, so every pixel kept was noise).
      if (lx < s.minSignificance * std::sqrt(noiseSquared)) continue;
      const Color e = x / static_cast<float>(f) + background;
      const uint64_t tile = static_cast<uint64_t>((r.y0 + row) / kTile) * 65536 + static_cast<uint64_t>((r.x0 + col) / kTile);
      out.push_back({Color(e / luminance(e)).log().cast<double>(), lx * lx / noiseSquared,
                     (static_cast<uint64_t>(frame) << 32) | tile});
    }
  return out;
}

// The colour (luminance 1, in log) the samples' weighted mean gives, leaving out those of unit
// `leftOut` (none: ~0).
Eigen::Array3d meanLogColour(const std::vector<ColourSample>& samples, uint64_t leftOut) {
  Eigen::Array3d sum = Eigen::Array3d::Zero();
  double total = 0;
  for (const ColourSample& p : samples)
    if (p.unit != leftOut) sum += p.weight * p.logColour, total += p.weight;
  const Eigen::Array3d logColour = sum / total;
  const Eigen::Array3d colour = logColour.exp();
  return logColour - std::log(0.2126 * colour[0] + 0.7152 * colour[1] + 0.0722 * colour[2]);
}

}  // namespace

double weightedMedian(std::vector<std::pair<double, double>> valueWeight) {
  if (valueWeight.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(valueWeight.begin(), valueWeight.end());
  double total = 0;
  for (const auto& [v, weight] : valueWeight) {
    DCHECK(weight > 0);
    total += weight;
  }
  double below = 0;
  for (const auto& [v, weight] : valueWeight) {
    below += weight;
    if (below >= 0.5 * total) return v;
  }
  return valueWeight.back().first;
}

Json SilhouetteColour::toJson() const {
  const auto finite = [](float v) { return std::isfinite(v) ? Json(v) : Json(nullptr); };
  return {{"colour", measured ? Json({colour[0], colour[1], colour[2]}) : Json(nullptr)},
          {"log_error", {finite(logError[0]), finite(logError[1]), finite(logError[2])}},
          {"pixels", pixels},
          {"frames", frames},
          {"known", known}};
}

std::vector<SilhouetteColour> measureSilhouetteColours(const Workspace& w, const FrameGains& gains,
                                                       const std::vector<int>& lights,
                                                       const std::vector<Color>& emission,
                                                       const std::vector<uint8_t>& emitter,
                                                       const SilhouetteColourSettings& s) {
  std::vector<SilhouetteColour> out;
  for (int light : lights) {
    CHECK(light >= 0 && light < static_cast<int>(emission.size()));
    std::vector<Vec3> vertices;
    for (size_t t = 0; t < w.mesh.triangles.size(); ++t)
      if (w.mesh.faceObject[t] == light)
        for (int k = 0; k < 3; ++k) vertices.push_back(w.mesh.positions[w.mesh.triangles[t][k]]);
    // The kept frames the light's triangles project into, then up to maxFrames of them, evenly.
    std::vector<uint32_t> candidates;
    for (uint32_t f : w.kept) {
      const FrameStats& stats = w.store->stats(f);
      if (regionAround(w.frames[f].camera, vertices, static_cast<int>(stats.downscale), static_cast<int>(stats.width),
                       static_cast<int>(stats.height), 0)
              .size() > 0)
        candidates.push_back(f);
    }
    std::vector<uint32_t> chosen;
    const size_t n = std::min(candidates.size(), static_cast<size_t>(s.maxFrames));
    for (size_t i = 0; i < n; ++i) chosen.push_back(candidates[i * candidates.size() / n]);
    std::vector<std::vector<ColourSample>> perFrame(chosen.size());
    tbb::parallel_for(size_t{0}, chosen.size(), [&](size_t i) {
      perFrame[i] = frameSamples(w, chosen[i], gains.gain(chosen[i]), light, vertices, luminance(emission[light]),
                                 emitter, s);
    });
    SilhouetteColour result;
    result.light = light;
    std::vector<ColourSample> samples;
    for (const auto& inFrame : perFrame) samples.insert(samples.end(), inFrame.begin(), inFrame.end());
    const auto count = [&] {
      std::vector<uint64_t> frames;
      for (const ColourSample& p : samples) frames.push_back(p.unit >> 32);
      std::sort(frames.begin(), frames.end());
      result.frames = static_cast<int>(std::unique(frames.begin(), frames.end()) - frames.begin());
      result.pixels = samples.size();
    };
    count();
    result.measured = result.pixels >= static_cast<size_t>(s.minPixels);
    if (result.measured) {
      // Pixels whose colour lies beyond kOutlierMads robust deviations of the weighted median in
      // some channel measure something else (a background the ring misjudged, another light).
      for (int c = 0; c < 3; ++c) {
        std::vector<std::pair<double, double>> values;
        for (const ColourSample& p : samples) values.emplace_back(p.logColour[c], p.weight);
        const double centre = weightedMedian(values);
        for (auto& [v, weight] : values) v = std::abs(v - centre);
        const double mad = 1.4826 * weightedMedian(values);
        if (mad > 0)
          std::erase_if(samples, [&](const ColourSample& p) { return std::abs(p.logColour[c] - centre) > kOutlierMads * mad; });
      }
      count();
      result.measured = result.pixels >= static_cast<size_t>(s.minPixels);
    }
    if (result.measured) {
      const Eigen::Array3d logColour = meanLogColour(samples, kNoUnit);
      result.colour = logColour.exp().cast<float>();
      // Jackknife over the units and, with more than one frame, over the frames (a frame's error in
      // its white balance or in its pose moves all of its pixels alike): the larger error. With
      // estimated gains one frame is not enough.
      const auto jackknife = [&](auto unitOf) {
        std::vector<uint64_t> units;
        for (const ColourSample& p : samples) units.push_back(unitOf(p.unit));
        std::sort(units.begin(), units.end());
        units.erase(std::unique(units.begin(), units.end()), units.end());
        if (units.size() < 2) return Eigen::Array3d::Constant(INFINITY).eval();
        std::vector<ColourSample> regrouped = samples;
        for (ColourSample& p : regrouped) p.unit = unitOf(p.unit);
        Eigen::Array3d mean = Eigen::Array3d::Zero(), squares = Eigen::Array3d::Zero();
        for (uint64_t u : units) {
          const Eigen::Array3d v = meanLogColour(regrouped, u);
          mean += v, squares += v.square();
        }
        const double n = static_cast<double>(units.size());
        mean /= n;
        return ((squares / n - mean.square()).max(0.0) * (n - 1)).sqrt().eval();
      };
      Eigen::Array3d error = jackknife([](uint64_t unit) { return unit; });
      if (gains.estimated() || result.frames > 1) error = error.max(jackknife([](uint64_t unit) { return unit >> 32; }));
      result.logError = error.cast<float>();
    }
    result.known = result.measured && result.colour.allFinite() &&
                   (result.logError <= static_cast<float>(s.maxLogError)).all();
    out.push_back(result);
  }
  return out;
}

}  // namespace relume
