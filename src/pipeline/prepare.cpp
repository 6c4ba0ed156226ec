#include "pipeline/prepare.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cstring>
#include <fstream>
#include <map>

#include "capture/frame_store.h"
#include "capture/objects.h"
#include "core/error.h"
#include "core/rng.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/image.h"
#include "io/json.h"
#include "scene/scene.h"
#include "scene/texel_map.h"

namespace relume {
namespace fs = std::filesystem;

namespace {

// Where a camera sees surface point p (normal n, winding side): in the image, facing, unoccluded.
std::optional<Vec2> observe(const Scene& scene, const Camera& cam, const Vec3& p, const Vec3& n) {
  const Vec3 toCam = cam.position - p;
  if (n.dot(toCam) <= 0.0f) return std::nullopt;
  const auto px = cam.project(p);
  if (!px || px->x() < 0.5f || px->y() < 0.5f || px->x() > cam.width - 0.5f || px->y() > cam.height - 0.5f) return std::nullopt;
  const float dist = toCam.norm();
  if (!(dist > 2 * rayEpsilon(cam.position))) return std::nullopt;  // at the camera: no segment to test
  const Vec3 dir = toCam / dist;
  const Vec3 o = p + rayEpsilon(p) * n;
  if (scene.occluded(o, dir, dist - 2 * rayEpsilon(cam.position))) return std::nullopt;
  return px;
}

std::string fingerprintOf(const std::vector<fs::path>& files, const std::string& extra) {
  uint64_t h = std::hash<std::string>{}(extra);
  for (const fs::path& f : files) {
    std::error_code ec;
    const auto size = fs::file_size(f, ec);
    const auto time = fs::last_write_time(f, ec).time_since_epoch().count();
    h = hashTuple({h, std::hash<std::string>{}(f.string()), static_cast<uint64_t>(size), static_cast<uint64_t>(time)});
  }
  return fmt::format("{:016x}", h);
}

fs::path findMesh(const fs::path& capture) {
  for (const char* name : {"mesh.ply", "mesh.obj"})
    if (fs::exists(capture / name)) return capture / name;
  fail("{}: no mesh.ply or mesh.obj in the capture folder", capture.string());
}

// Streaming median in O(1) memory per texel: a coarse log histogram locates the median's bin,
// a second pass over the observations refines it with sub-bins inside that bin.
class MedianSketch {
 public:
  static constexpr int kBins = 16, kSub = 32;
  static constexpr float kLogMin = -4.0f, kLogMax = 4.0f;
  explicit MedianSketch(size_t texels) : coarse_(texels * 3 * kBins, 0), count_(texels, 0) {}
  static int binOfLog(float l) { return std::clamp(static_cast<int>((l - kLogMin) / width()), 0, kBins - 1); }
  void addCoarse(size_t t, const Color& c) {
    for (int ch = 0; ch < 3; ++ch) {
      uint16_t& b = coarse_[(t * 3 + ch) * kBins + binOfLog(std::log10(std::max(c[ch], 1e-12f)))];
      b = static_cast<uint16_t>(std::min(65535, b + 1));
    }
    count_[t] = std::min<uint32_t>(count_[t] + 1, 65535);
  }
  // After the coarse pass: pick each channel's median bin, reset storage for the fine pass.
  void startFine() {
    target_.assign(count_.size() * 3, 0);
    below_.assign(count_.size() * 3, 0);
    binIndex_.assign(count_.size() * 3, 0);
    for (size_t t = 0; t < count_.size(); ++t)
      for (int ch = 0; ch < 3; ++ch) {
        const size_t k = t * 3 + ch;
        const uint32_t half = (count_[t] + 1) / 2;
        uint32_t cum = 0;
        int b = 0;
        for (; b < kBins; ++b) {
          if (cum + coarse_[k * kBins + b] >= half) break;
          cum += coarse_[k * kBins + b];
        }
        binIndex_[k] = static_cast<uint8_t>(std::min(b, kBins - 1));
        below_[k] = cum;
        target_[k] = half;
      }
    coarse_.assign(count_.size() * 3 * kSub, 0);  // reused as the fine histogram
  }
  void addFine(size_t t, const Color& c) {
    for (int ch = 0; ch < 3; ++ch) {
      const size_t k = t * 3 + ch;
      const float lo = kLogMin + binIndex_[k] * width();
      const float l = std::log10(std::max(c[ch], 1e-12f));
      if (binIndex_[k] != binOfLog(l)) continue;
      const int s = std::clamp(static_cast<int>((l - lo) / (width() / kSub)), 0, kSub - 1);
      uint16_t& b = coarse_[k * kSub + s];
      b = static_cast<uint16_t>(std::min(65535, b + 1));
    }
  }
  uint32_t count(size_t t) const { return count_[t]; }
  Color median(size_t t) const {
    Color out;
    for (int ch = 0; ch < 3; ++ch) {
      const size_t k = t * 3 + ch;
      uint32_t cum = below_[k];
      const float lo = kLogMin + binIndex_[k] * width(), sub = width() / kSub;
      float l = lo + width();
      for (int s = 0; s < kSub; ++s) {
        const uint16_t n = coarse_[k * kSub + s];
        if (n > 0 && cum + n >= target_[k]) {
          l = lo + sub * (s + (static_cast<float>(target_[k] - cum) - 0.5f) / n);  // interpolate inside the sub-bin
          break;
        }
        cum += n;
      }
      out[ch] = l <= kLogMin + 1e-3f ? 0.0f : std::pow(10.0f, l);
    }
    return out;
  }

 private:
  static constexpr float width() { return (kLogMax - kLogMin) / kBins; }
  std::vector<uint16_t> coarse_;
  std::vector<uint32_t> count_;
  std::vector<uint32_t> target_, below_;
  std::vector<uint8_t> binIndex_;
};

Image falseColour(const std::vector<uint32_t>& counts, int res) {
  uint32_t maxCount = 1;
  for (uint32_t c : counts) maxCount = std::max(maxCount, c);
  Image img(res, res);
  for (size_t i = 0; i < counts.size(); ++i) {
    if (counts[i] == 0) continue;
    const float t = std::log1p(static_cast<float>(counts[i])) / std::log1p(static_cast<float>(maxCount));
    // Blue (seen once) -> green -> yellow -> red (seen most); black = never.
    const Color c = t < 0.5f ? Color(0, 2 * t, 1 - 2 * t) : Color(2 * (t - 0.5f), 1 - 2 * (t - 0.5f) * 0.5f, 0);
    img.rgb[3 * i] = srgbToLinear(c[0]), img.rgb[3 * i + 1] = srgbToLinear(c[1]), img.rgb[3 * i + 2] = srgbToLinear(c[2]);
  }
  return img;
}

}  // namespace

VisibilityIndex buildVisibilityIndex(const Scene& scene, const TexelMap& map, const std::vector<Frame>& frames,
                                     const std::vector<size_t>& use, int tileTexels, int samplesPerTile) {
  const TriangleMesh& mesh = scene.mesh();
  const int res = map.resolution();
  VisibilityIndex vis;
  vis.resolution = res, vis.tileTexels = tileTexels, vis.tilesPerSide = res / tileTexels;
  const size_t tiles = static_cast<size_t>(vis.tilesPerSide) * vis.tilesPerSide;
  std::vector<std::vector<uint32_t>> perTile(tiles);
  Progress progress("visibility", tiles);
  tbb::parallel_for(size_t{0}, tiles, [&](size_t tile) {
    const int tx = static_cast<int>(tile % vis.tilesPerSide), ty = static_cast<int>(tile / vis.tilesPerSide);
    std::vector<size_t> texels;
    for (int y = ty * tileTexels; y < (ty + 1) * tileTexels; ++y)
      for (int x = tx * tileTexels; x < (tx + 1) * tileTexels; ++x)
        if (map.valid(static_cast<size_t>(y) * res + x)) texels.push_back(static_cast<size_t>(y) * res + x);
    if (!texels.empty()) {
      // Evenly spread test points over the tile's valid texels (deterministic).
      std::vector<std::pair<Vec3, Vec3>> samples;
      const int n = std::min<int>(samplesPerTile, static_cast<int>(texels.size()));
      for (int s = 0; s < n; ++s) {
        const size_t texel = texels[(texels.size() * (2 * s + 1)) / (2 * n)];
        samples.push_back({map.point(mesh, texel), map.normal(mesh, texel)});
      }
      for (size_t k : use)
        for (const auto& [p, nrm] : samples)
          if (observe(scene, frames[k].camera, p, nrm)) {
            perTile[tile].push_back(static_cast<uint32_t>(k));
            break;
          }
    }
    progress.advance();
  });
  vis.offsets.push_back(0);
  for (const auto& f : perTile) {
    vis.frames.insert(vis.frames.end(), f.begin(), f.end());
    vis.offsets.push_back(static_cast<uint32_t>(vis.frames.size()));
  }
  return vis;
}

void VisibilityIndex::write(const fs::path& path) const {
  std::string bytes = "RLMVIS01";
  auto put = [&](const void* p, size_t n) { bytes.append(static_cast<const char*>(p), n); };
  const uint32_t header[4] = {static_cast<uint32_t>(resolution), static_cast<uint32_t>(tileTexels),
                              static_cast<uint32_t>(tilesPerSide), static_cast<uint32_t>(frames.size())};
  put(header, sizeof(header));
  put(offsets.data(), offsets.size() * sizeof(uint32_t));
  put(frames.data(), frames.size() * sizeof(uint32_t));
  writeTextAtomically(path, bytes);
}

VisibilityIndex VisibilityIndex::read(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 24 || bytes.compare(0, 8, "RLMVIS01") != 0) fail("{}: not a relume visibility index", path.string());
  uint32_t header[4];
  std::memcpy(header, bytes.data() + 8, sizeof(header));
  VisibilityIndex v;
  v.resolution = static_cast<int>(header[0]), v.tileTexels = static_cast<int>(header[1]), v.tilesPerSide = static_cast<int>(header[2]);
  const size_t tiles = static_cast<size_t>(v.tilesPerSide) * v.tilesPerSide;
  if (v.tilesPerSide <= 0 || v.tilesPerSide > 65536 || bytes.size() != 24 + (tiles + 1 + header[3]) * sizeof(uint32_t))
    fail("{}: visibility index is truncated or corrupt", path.string());
  v.offsets.resize(tiles + 1);
  v.frames.resize(header[3]);
  std::memcpy(v.offsets.data(), bytes.data() + 24, v.offsets.size() * sizeof(uint32_t));
  std::memcpy(v.frames.data(), bytes.data() + 24 + v.offsets.size() * sizeof(uint32_t), v.frames.size() * sizeof(uint32_t));
  if (v.offsets.back() != v.frames.size()) fail("{}: visibility index offsets are inconsistent", path.string());
  return v;
}

PrepareSummary prepareCapture(const fs::path& capture, const fs::path& work, const PrepareOptions& o) {
  Timer total;
  fs::create_directories(work);
  const fs::path transformsPath = capture / "transforms.json";
  const fs::path meshPath = findMesh(capture);
  const Capture cap = readTransforms(transformsPath);
  Json report = fs::exists(work / "prepare.json") ? readJson(work / "prepare.json") : Json::object();
  Json phases = report.value("phases", Json::object());
  const int initRes = o.resolutions.front();
  if (initRes % o.tileTexels != 0) fail("prepare: init resolution {} is not a multiple of the tile size {}", initRes, o.tileTexels);
  for (int r : o.resolutions)
    if (r < o.atlas.gutterResolution || r % o.atlas.gutterResolution != 0)
      fail("prepare: resolution {} must be a multiple of the atlas gutter resolution {}", r, o.atlas.gutterResolution);

  // A phase is current when its fingerprint (inputs + options + the previous phase) is unchanged.
  auto runPhase = [&](const char* name, const std::string& fingerprint, const std::vector<fs::path>& outputs,
                      const std::function<Json()>& body) {
    bool current = !o.force && phases.contains(name) && phases[name].value("fingerprint", "") == fingerprint;
    for (const fs::path& out : outputs) current = current && fs::exists(out);
    if (current) {
      spdlog::info("prepare: {} is up to date", name);
      return;
    }
    Timer t;
    Json result = body();
    result["fingerprint"] = fingerprint;
    result["seconds"] = t.seconds();
    phases[name] = result;
    report["phases"] = phases;
    writeJson(work / "prepare.json", report);  // after each phase: an interrupted run keeps its progress
    spdlog::info("prepare: {} done in {:.1f}s", name, t.seconds());
  };

  // Atlas.
  // "atlas2": the charting/packing version, so work folders made by an older atlas are re-charted.
  const std::string atlasPrint = fingerprintOf({meshPath}, fmt::format("atlas2 {} {} {} {}", o.atlas.gutterResolution,
                                                                       o.atlas.gutterTexels, o.atlas.coneDegrees, o.atlas.planarDegrees));
  runPhase("atlas", atlasPrint, {work / "atlas_mesh.ply"}, [&] {
    TriangleMesh mesh = loadMesh(meshPath);
    AtlasReport ar;
    const TriangleMesh atlas = buildAtlas(mesh, o.atlas, &ar);
    writePly(work / "atlas_mesh.ply", atlas.toData());
    spdlog::info("atlas: {}", ar.summary());
    // Names from objects.json, else from the mesh file (OBJ groups).
    Json names = Json::object();
    for (size_t id = 0; id < mesh.objectNames.size(); ++id) names[std::to_string(id)] = mesh.objectNames[id];
    if (fs::exists(capture / "objects.json"))
      for (const auto& [id, name] : readObjectNames(capture / "objects.json")) names[std::to_string(id)] = name;
    return Json{{"triangles", atlas.triangles.size()}, {"objects", atlas.objectCount}, {"dropped_degenerate", mesh.droppedDegenerate},
                {"dropped_coincident", mesh.droppedCoincident},
                {"kept_input_uv", ar.keptInputUv}, {"charts", ar.charts}, {"lscm_charts", ar.lscmCharts},
                {"split_charts", ar.splitCharts}, {"merged_charts", ar.mergedCharts}, {"packing_efficiency", ar.packingEfficiency},
                {"texels_per_metre", ar.texelsPerMetre}, {"stretch_p05_median_p95", {ar.stretchP05, ar.stretchMedian, ar.stretchP95}},
                {"uv_overlaps", ar.uvOverlaps}, {"atlas_seconds", ar.seconds},
                {"object_names", names}};
  });
  const TriangleMesh mesh = loadMesh(work / "atlas_mesh.ply");
  const Scene scene(mesh);

  // Frames: convert, then filter.
  std::vector<fs::path> imagePaths{transformsPath};
  for (const Frame& f : cap.frames) imagePaths.push_back(f.image);
  const std::string framesPrint = fingerprintOf(imagePaths, fmt::format("frames {} {} {} {} {}", o.maxOverexposed, o.maxUnderexposed,
                                                                         o.maxSpeed, o.maxAngularSpeed, o.downscale));
  runPhase("frames", framesPrint, {work / "frames.bin"}, [&] {
    Progress progress("frame cache", cap.frames.size());
    const std::vector<FrameStats> stats = writeFrameStore(work / "frames.bin", cap.frames, o.downscale, [&] { progress.advance(); });
    Json kept = Json::array(), dropped = Json::array();
    std::map<std::string, int> reasons;
    for (size_t i = 0; i < cap.frames.size(); ++i) {
      std::string reason;
      const Camera& c = cap.frames[i].camera;
      // Camera motion to the nearer neighbour: a fast frame moves far from both neighbours,
      // whereas a frame next to a jump still has one close neighbour.
      float speed = INFINITY, angle = INFINITY;
      for (long j : {static_cast<long>(i) - 1, static_cast<long>(i) + 1}) {
        if (j < 0 || j >= static_cast<long>(cap.frames.size())) continue;
        const Camera& d = cap.frames[j].camera;
        speed = std::min(speed, (c.position - d.position).norm());
        angle = std::min(angle, std::acos(std::clamp(((c.rotation.transpose() * d.rotation).trace() - 1.0f) / 2.0f, -1.0f, 1.0f)) * 180.0f / kPi);
      }
      if (!std::isfinite(speed)) speed = angle = 0;
      if (stats[i].overexposed > o.maxOverexposed) reason = fmt::format("overexposed ({:.0f}% saturated)", 100 * stats[i].overexposed);
      else if (stats[i].underexposed > o.maxUnderexposed) reason = fmt::format("underexposed ({:.0f}% dark)", 100 * stats[i].underexposed);
      else if (speed > o.maxSpeed) reason = fmt::format("motion blur (moved {:.2f} m per frame)", speed);
      else if (angle > o.maxAngularSpeed) reason = fmt::format("motion blur (turned {:.1f} deg per frame)", angle);
      if (reason.empty()) {
        kept.push_back(i);
      } else {
        spdlog::warn("frame {} ({}) dropped: {}", i, cap.frames[i].image.filename().string(), reason);
        dropped.push_back({{"frame", i}, {"image", cap.frames[i].image.filename().string()}, {"reason", reason}});
        ++reasons[reason.substr(0, reason.find(' '))];
      }
    }
    Json masked = Json::object();  // frames with NaN/Inf pixels (masked, never used)
    for (size_t i = 0; i < stats.size(); ++i)
      if (stats[i].masked > 0) masked[std::to_string(i)] = stats[i].masked;
    return Json{{"frames", cap.frames.size()}, {"kept", kept}, {"dropped", dropped}, {"dropped_by_reason", reasons},
                {"masked_pixel_fraction", masked},
                {"bytes", fs::file_size(work / "frames.bin")}};
  });
  const std::vector<size_t> kept = phases["frames"]["kept"].get<std::vector<size_t>>();
  if (kept.empty()) fail("prepare: every frame was dropped (see {})", (work / "prepare.json").string());

  // Visibility index over tiles of the init resolution.
  const TexelMap initMap(mesh, initRes);
  const int tilesPerSide = initRes / o.tileTexels;
  const std::string visPrint = fingerprintOf({}, fmt::format("vis {} {} {} {} {}", atlasPrint, framesPrint, initRes, o.tileTexels,
                                                             o.samplesPerTile));
  runPhase("visibility", visPrint, {work / "visibility.bin"}, [&] {
    const size_t skippedBefore = scene.skippedRays();
    const VisibilityIndex vis = buildVisibilityIndex(scene, initMap, cap.frames, kept, o.tileTexels, o.samplesPerTile);
    const size_t tiles = vis.offsets.size() - 1;
    vis.write(work / "visibility.bin");
    size_t seen = 0;
    for (size_t t = 0; t < tiles; ++t) seen += vis.offsets[t + 1] > vis.offsets[t];
    std::vector<char> frameSees(cap.frames.size(), 0);
    for (uint32_t f : vis.frames) frameSees[f] = 1;
    Json blind = Json::array();
    for (size_t k : kept)
      if (!frameSees[k]) {
        spdlog::warn("frame {} ({}) sees no surface of the mesh: skipped", k, cap.frames[k].image.filename().string());
        blind.push_back(k);
      }
    return Json{{"tiles", tiles}, {"tiles_seen", seen}, {"entries", vis.frames.size()}, {"bytes", vis.bytes()},
                {"frames_seeing_nothing", blind}, {"skipped_rays", scene.skippedRays() - skippedBefore},
                {"mean_frames_per_seen_tile", seen ? double(vis.frames.size()) / seen : 0.0}};
  });

  // Initial albedo (streaming median of observed radiance) and coverage.
  const std::string initPrint = fingerprintOf({}, fmt::format("init {} {}", visPrint, static_cast<int>(o.init)));
  runPhase("init", initPrint, {work / "albedo_init.exr", work / "coverage.exr", work / "coverage.png"}, [&] {
    const size_t skippedBefore = scene.skippedRays();
    const VisibilityIndex vis = VisibilityIndex::read(work / "visibility.bin");
    const FrameStore store(work / "frames.bin");
    // For each frame, its tiles and its position in each tile's frame list.
    std::vector<std::vector<std::pair<uint32_t, uint32_t>>> tilesOf(cap.frames.size());
    for (size_t t = 0; t + 1 < vis.offsets.size(); ++t)
      for (uint32_t k = vis.offsets[t]; k < vis.offsets[t + 1]; ++k)
        tilesOf[vis.frames[k]].push_back({static_cast<uint32_t>(t), k - vis.offsets[t]});
    // One bit per (texel, frame of its tile) remembers which observations the first pass found
    // unoccluded, so a second pass re-projects without tracing again.
    const size_t tileArea = static_cast<size_t>(o.tileTexels) * o.tileTexels;
    std::vector<std::vector<uint64_t>> seenBits(vis.offsets.size() - 1);
    for (size_t t = 0; t + 1 < vis.offsets.size(); ++t) seenBits[t].assign((tileArea * (vis.offsets[t + 1] - vis.offsets[t]) + 63) / 64, 0);
    const size_t texels = initMap.texelCount();
    // Each texel's surface point and normal, computed once rather than once per frame.
    std::vector<Vec3> texelPoint(texels), texelNormal(texels);
    std::atomic<size_t> fellBack{0};
    tbb::parallel_for(size_t{0}, texels, [&](size_t t) {
      if (!initMap.valid(t)) return;
      bool geometric = false;
      texelPoint[t] = initMap.point(mesh, t);
      texelNormal[t] = initMap.normal(mesh, t, &geometric);
      if (geometric) fellBack.fetch_add(1, std::memory_order_relaxed);
    });
    MedianSketch sketch(texels);
    std::vector<Eigen::Array3d> sum(o.init == InitStatistic::Mean ? texels : 0, Eigen::Array3d::Zero());
    std::vector<uint32_t> coverage(texels, 0);
    // Each pass visits frames in order and, inside a frame, its tiles in parallel: a texel (and
    // its tile's bits) is only ever updated by one thread at a time, so nothing needs atomics.
    int passIndex = 0;
    auto pass = [&](const char* label, const std::function<void(size_t, const Color&)>& add) {
      const bool traced = passIndex++ > 0;
      Progress progress(label, kept.size());
      for (size_t k : kept) {
        tbb::parallel_for(size_t{0}, tilesOf[k].size(), [&](size_t i) {
          const auto [tile, slot] = tilesOf[k][i];
          std::vector<uint64_t>& bits = seenBits[tile];
          const int tx = static_cast<int>(tile) % tilesPerSide, ty = static_cast<int>(tile) / tilesPerSide;
          for (int y = ty * o.tileTexels; y < (ty + 1) * o.tileTexels; ++y)
            for (int x = tx * o.tileTexels; x < (tx + 1) * o.tileTexels; ++x) {
              const size_t texel = static_cast<size_t>(y) * initRes + x;
              if (!initMap.valid(texel)) continue;
              const size_t bit = (static_cast<size_t>(y - ty * o.tileTexels) * o.tileTexels + (x - tx * o.tileTexels)) +
                                 tileArea * slot;
              std::optional<Vec2> px;
              if (traced) {
                if (!(bits[bit / 64] >> (bit % 64) & 1)) continue;
                px = cap.frames[k].camera.project(texelPoint[texel]);
              } else {
                px = observe(scene, cap.frames[k].camera, texelPoint[texel], texelNormal[texel]);
              }
              if (!px) continue;
              const auto c = store.bilinear(k, *px);
              if (!c) continue;
              if (!traced) bits[bit / 64] |= uint64_t{1} << (bit % 64);
              add(texel, *c);
            }
        });
        progress.advance();
      }
    };
    if (o.init == InitStatistic::Median) {
      pass("median (coarse)", [&](size_t t, const Color& c) { sketch.addCoarse(t, c); });
      sketch.startFine();
      pass("median (fine)", [&](size_t t, const Color& c) { sketch.addFine(t, c); });
      for (size_t t = 0; t < texels; ++t) coverage[t] = sketch.count(t);
    } else {
      pass("mean", [&](size_t t, const Color& c) { sum[t] += c.cast<double>(), ++coverage[t]; });
    }
    Image albedo(initRes, initRes), cov(initRes, initRes);
    size_t valid = 0, unobserved = 0;
    std::vector<Eigen::Array4d> objectMean(mesh.objectCount, Eigen::Array4d::Zero());
    for (size_t t = 0; t < texels; ++t) {
      if (!initMap.valid(t)) continue;
      ++valid;
      cov.set(static_cast<int>(t % initRes), static_cast<int>(t / initRes), Color::Constant(static_cast<float>(coverage[t])));
      if (coverage[t] == 0) {
        ++unobserved;
        continue;
      }
      const Color v = o.init == InitStatistic::Median ? sketch.median(t) : Color((sum[t] / coverage[t]).cast<float>());
      albedo.set(static_cast<int>(t % initRes), static_cast<int>(t / initRes), v);
      const Eigen::Array3d vd = v.cast<double>();
      objectMean[mesh.faceObject[initMap.triangle(t)]] += Eigen::Array4d(vd[0], vd[1], vd[2], 1.0);
    }
    // Texels no frame saw start from their object's average (or mid-grey).
    for (size_t t = 0; t < texels; ++t) {
      if (!initMap.valid(t) || coverage[t] > 0) continue;
      const Eigen::Array4d& m = objectMean[mesh.faceObject[initMap.triangle(t)]];
      albedo.set(static_cast<int>(t % initRes), static_cast<int>(t / initRes),
                 m[3] > 0 ? Color((m.head<3>() / m[3]).cast<float>()) : Color::Constant(0.5f));
    }
    writeExr(work / "albedo_init.exr", albedo);
    writePng(work / "albedo_init.png", albedo);  // preview
    writeExr(work / "coverage.exr", cov);
    writePng(work / "coverage.png", falseColour(coverage, initRes));
    const double fraction = valid ? double(unobserved) / valid : 0.0;
    spdlog::info("init: {} valid texels at {}^2, {:.2f}% never observed", valid, initRes, 100 * fraction);
    return Json{{"resolution", initRes}, {"statistic", o.init == InitStatistic::Median ? "median" : "mean"},
                {"valid_texels", valid}, {"unobserved_texels", unobserved}, {"fraction_unobserved", fraction},
                {"texels_geometric_normal", fellBack.load()}, {"skipped_rays", scene.skippedRays() - skippedBefore}};
  });

  PrepareSummary s;
  s.frames = cap.frames.size();
  s.keptFrames = kept.size();
  s.triangles = mesh.triangles.size();
  s.fractionUnobserved = phases["init"].value("fraction_unobserved", 0.0);
  s.seconds = total.seconds();
  report["resolutions"] = o.resolutions;
  report["texel_map_bytes_per_texel"] = sizeof(uint32_t);
  report["peak_rss_mib"] = peakRssMiB();
  report["seconds_total_last_run"] = s.seconds;
  writeJson(work / "prepare.json", report);
  return s;
}

}  // namespace relume
