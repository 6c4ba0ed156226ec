#include "product/prepare.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <map>
#include <optional>

#include "capture/capture_folder.h"
#include "capture/duplicate_frames.h"
#include "capture/frame_store.h"
#include "capture/objects.h"
#include "capture/photometric_consistency.h"
#include "core/error.h"
#include "core/ranks.h"
#include "core/rng.h"
#include "core/system.h"
#include "io/atomic_file.h"
#include "io/file_system.h"
#include "io/image.h"
#include "io/json.h"
#include "product/confidence.h"
#include "product/frame_gains.h"
#include "product/prepare_memory.h"
#include "scene/scene.h"
#include "scene/segmentation.h"
#include "scene/texel_map.h"
#include "sampling/face_appearance.h"
#include "sampling/median_sketch.h"
#include "sampling/visibility.h"

namespace relume {
namespace fs = std::filesystem;

namespace {

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

// The previous run's report, whose fingerprints say which phases are current. --force ignores it;
// an unreadable one (hand-edited, truncated) only means every phase is redone.
Json previousReport(const fs::path& file, bool force) {
  if (force || !pathExists(file)) return Json::object();
  try {
    Json report = readJson(file);
    if (report.is_object() && report.value("phases", Json::object()).is_object()) return report;
    spdlog::warn("{}: not a prepare report; rebuilding every phase", file.string());
  } catch (const Error& e) {
    spdlog::warn("{}; rebuilding every phase", e.what());
  }
  return Json::object();
}

Image falseColour(const std::vector<uint32_t>& counts, int res) {
  uint32_t maxCount = 1;
  for (uint32_t c : counts) maxCount = std::max(maxCount, c);
  Image img(res, res);
  for (size_t i = 0; i < counts.size(); ++i) {
    if (counts[i] == 0) continue;
    const float t = std::log1p(static_cast<float>(counts[i])) / std::log1p(static_cast<float>(maxCount));
    // Blue (seen once) -> green -> yellow -> red (seen most); black = never.
    const Color c = t < 0.5f ? Color(0, 2 * t, 1 - 2 * t) : Color(2 * (t - 0.5f), 1 - 2 * (t - 0.5f) * 0.5f, 0);
    img.rgb[3 * i] = srgbToLinear(c[0]), img.rgb[3 * i + 1] = srgbToLinear(c[1]),
                img.rgb[3 * i + 2] = srgbToLinear(c[2]);
  }
  return img;
}

// The phases, in order; each returns what prepare.json records of it.

// Segmentation: objects for a mesh that has none (scene/segmentation.h), from the faces' geometry
// and what the kept frames show of them. Writes segments.bin and objects.json (per object: faces,
// area, median radiance, clipped share).
Json segmentationPhase(const fs::path& meshPath, const Capture& cap, const std::vector<size_t>& kept,
                       const fs::path& work, const PrepareOptions& o) {
  const Scene scene(loadMesh(meshPath));
  const TriangleMesh& mesh = scene.mesh();
  const FrameStore store(work / "frames.bin");
  Timer observing;
  const std::vector<FaceAppearance> appearance = observeFaces(scene, cap.frames, store, kept, o.faceAppearance);
  const double observeSeconds = observing.seconds();
  const Segmentation seg = segmentMesh(mesh, appearance, o.segmentationOptions);
  struct Object {
    size_t faces = 0;
    double area = 0, observedArea = 0, clipped = 0;
    Eigen::Array3d logSum = Eigen::Array3d::Zero();
  };
  std::vector<Object> objects(seg.objects);
  size_t observedFaces = 0;
  for (size_t f = 0; f < mesh.triangles.size(); ++f) {
    Object& ob = objects[seg.faceObject[f]];
    const double area = mesh.faceArea[f];
    ++ob.faces, ob.area += area;
    if (!appearance[f].observed) continue;
    ++observedFaces;
    ob.observedArea += area, ob.clipped += area * appearance[f].clippedFraction;
    ob.logSum += area * appearance[f].logRadiance.cast<double>();
  }
  Json list = Json::array();
  for (int id = 0; id < seg.objects; ++id) {
    const Object& ob = objects[id];
    Json entry{{"id", id}, {"name", fmt::format("segment {}", id)}, {"faces", ob.faces}, {"area", ob.area}};
    if (ob.observedArea > 0) {
      const Eigen::Array3d c = (ob.logSum / ob.observedArea).exp();
      entry["radiance"] = {c[0], c[1], c[2]};
      entry["clipped_fraction"] = ob.clipped / ob.observedArea;
    }
    list.push_back(entry);
  }
  writeFaceObjects(work / "segments.bin", seg.faceObject);
  writeJson(work / "objects.json", Json{{"objects", list}});
  spdlog::info(
      "segmentation: {} objects ({} connected components, {} regions grown, {} small ones merged, {} kept for their "
      "brightness, {} isolated); {} of {} faces seen",
      seg.objects, seg.components, seg.grownRegions, seg.mergedSmall, seg.keptSmallBright, seg.isolatedSmall,
      observedFaces, mesh.triangles.size());
  return Json{{"objects", seg.objects},
              {"components", seg.components},
              {"grown_regions", seg.grownRegions},
              {"merged_small", seg.mergedSmall},
              {"kept_small_bright", seg.keptSmallBright},
              {"isolated_small", seg.isolatedSmall},
              {"faces", mesh.triangles.size()},
              {"faces_observed", observedFaces},
              {"observe_seconds", observeSeconds}};
}

// Atlas: the mesh charted and packed into one uv atlas (scene/atlas.h), with the object names
// from objects.json, else from the mesh file (OBJ groups); or with the computed segmentation's
// objects when `segments` names its file.
Json atlasPhase(const fs::path& capture, const fs::path& meshPath, const fs::path& work, const PrepareOptions& o,
                const std::optional<fs::path>& segments) {
  TriangleMesh mesh = loadMesh(meshPath);
  Json names = Json::object();
  if (segments) {
    mesh.faceObject = readFaceObjects(*segments, mesh.triangles.size());
    mesh.objectCount = 1 + *std::max_element(mesh.faceObject.begin(), mesh.faceObject.end());
    mesh.objectNames.clear();
    for (const auto& [id, name] : readObjectNames(work / "objects.json")) names[std::to_string(id)] = name;
  }
  AtlasReport ar;
  const TriangleMesh atlas = buildAtlas(mesh, o.atlas, &ar);
  writePly(work / "atlas_mesh.ply", atlas.toData());
  spdlog::info("atlas: {}", ar.summary());
  // Names from objects.json, else from the mesh file (OBJ groups).
  if (!segments) {
    for (size_t id = 0; id < mesh.objectNames.size(); ++id) names[std::to_string(id)] = mesh.objectNames[id];
    if (pathExists(capture / "objects.json"))
      for (const auto& [id, name] : readObjectNames(capture / "objects.json")) names[std::to_string(id)] = name;
  }
  return Json{{"triangles", atlas.triangles.size()},
              {"objects", atlas.objectCount},
              {"dropped_degenerate", mesh.droppedDegenerate},
              {"dropped_coincident", mesh.droppedCoincident},
              {"kept_input_uv", ar.keptInputUv},
              {"charts", ar.charts},
              {"lscm_charts", ar.lscmCharts},
              {"split_charts", ar.splitCharts},
              {"merged_charts", ar.mergedCharts},
              {"hollow_charts", ar.hollowCharts},
              {"shared_blocks", ar.sharedBlocks},
              {"charts_in_shared_blocks", ar.blockedCharts},
              {"surface_in_shared_blocks", ar.blockedSurface},
              {"packing_efficiency", ar.packingEfficiency},
              {"texels_per_metre", ar.texelsPerMetre},
              {"gutter_resolution", o.atlas.gutterResolution},
              {"stretch_p05_median_p95", {ar.stretchP05, ar.stretchMedian, ar.stretchP95}},
              {"uv_overlaps", ar.uvOverlaps},
              {"atlas_seconds", ar.seconds},
              {"object_names", names}};
}

// Why frame i is dropped, or "" to keep it: too many saturated or dark pixels, or motion blur
// (camera motion to the nearer neighbour: a fast frame moves far from both neighbours, whereas a
// frame next to a jump still has one close neighbour).
std::string dropReason(const Capture& cap, size_t i, const FrameStats& stats, const PrepareOptions& o) {
  std::string reason;
  const Camera& c = cap.frames[i].camera;
  float speed = INFINITY, angle = INFINITY;
  for (long j : {static_cast<long>(i) - 1, static_cast<long>(i) + 1}) {
    if (j < 0 || j >= static_cast<long>(cap.frames.size())) continue;
    const Camera& d = cap.frames[j].camera;
    speed = std::min(speed, (c.position - d.position).norm());
    angle = std::min(angle,
                     std::acos(std::clamp(((c.rotation.transpose() * d.rotation).trace() - 1.0f) / 2.0f, -1.0f, 1.0f)) *
                         180.0f / kPi);
  }
  if (!std::isfinite(speed)) speed = angle = 0;
  if (stats.overexposed > o.maxOverexposed)
    reason = fmt::format("overexposed ({:.0f}% saturated)", 100 * stats.overexposed);
  else if (stats.underexposed > o.maxUnderexposed)
    reason = fmt::format("underexposed ({:.0f}% dark)", 100 * stats.underexposed);
  else if (speed > o.maxSpeed)
    reason = fmt::format("motion blur (moved {:.2f} m per frame)", speed);
  else if (angle > o.maxAngularSpeed)
    reason = fmt::format("motion blur (turned {:.1f} deg per frame)", angle);
  return reason;
}

// Frames: every frame converted into the cache (half floats, one memory-mapped file), then
// filtered. A duplicate (capture/duplicate_frames.h) is dropped for that reason alone, so it is
// counted once.
Json framesPhase(const Capture& cap, const std::vector<DuplicateFrame>& duplicates, const fs::path& work,
                 const PrepareOptions& o) {
  size_t ownFrames = 0;  // over MPI ranks, the frames this rank decodes (writeFrameStore)
  for (size_t i = 0; i < cap.frames.size(); ++i) ownFrames += Ranks::world().ownsChunk(i);
  Progress progress("frame cache", ownFrames);
  const std::vector<FrameStats> stats =
      writeFrameStore(work / "frames.bin", cap.frames, o.downscale, o.encodingClips, [&] { progress.advance(); });
  Json kept = Json::array(), dropped = Json::array();
  std::map<std::string, int> reasons;
  std::vector<std::string> duplicateOf(cap.frames.size());
  for (const DuplicateFrame& d : duplicates) duplicateOf[d.frame] = d.reason;
  for (size_t i = 0; i < cap.frames.size(); ++i) {
    const std::string reason = duplicateOf[i].empty() ? dropReason(cap, i, stats[i], o) : duplicateOf[i];
    if (reason.empty()) {
      kept.push_back(i);
    } else {
      spdlog::warn("frame {} ({}) dropped: {}", i, cap.frames[i].image.filename().string(), reason);
      dropped.push_back({{"frame", i}, {"image", cap.frames[i].image.filename().string()}, {"reason", reason}});
      ++reasons[reason.substr(0, reason.find(' '))];
    }
  }
  Json masked = Json::object();  // frames with NaN/Inf pixels (masked, never used)
  std::map<std::string, int> encodings;
  Json saturated = Json::object();  // frames with saturated pixels: the fraction (they bound the loss one-sidedly)
  for (size_t i = 0; i < stats.size(); ++i) {
    if (stats[i].masked > 0) masked[std::to_string(i)] = stats[i].masked;
    if (stats[i].overexposed > 0) saturated[std::to_string(i)] = stats[i].overexposed;
    ++encodings[stats[i].bits ? fmt::format("{}-bit, response {}", stats[i].bits, cap.frames[i].response.describe())
                              : std::string("float (linear)")];
  }
  return Json{{"frames", cap.frames.size()},
              {"encodings", encodings},
              {"saturated_pixel_fraction", saturated},
              {"kept", kept},
              {"dropped", dropped},
              {"dropped_by_reason", reasons},
              {"masked_pixel_fraction", masked},
              {"bytes", fileSize(work / "frames.bin")}};
}

// Visibility: which kept frames see which tile of the init-resolution atlas.
Json visibilityPhase(const Scene& scene, const TexelMap& initMap, const Capture& cap, const std::vector<size_t>& kept,
                     const fs::path& work, const PrepareOptions& o) {
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
  return Json{{"tiles", tiles},
              {"tiles_seen", seen},
              {"entries", vis.frames.size()},
              {"bytes", vis.bytes()},
              {"frames_seeing_nothing", blind},
              {"skipped_rays", scene.skippedRays() - skippedBefore},
              {"mean_frames_per_seen_tile", seen ? double(vis.frames.size()) / seen : 0.0}};
}

// Every observation of every init-resolution texel by the kept frames, visited frame by frame:
// the first pass traces each (texel, frame) pair for occlusion and remembers the unoccluded ones
// in one bit each, so later passes re-project without tracing again. Over MPI ranks each rank
// visits the texel rows it owns (row y by rank y mod N), in every pass.
class TexelObservations {
 public:
  TexelObservations(const Scene& scene, const TexelMap& initMap, const Capture& cap, const std::vector<size_t>& kept,
                    const VisibilityIndex& vis, const FrameStore& store, int tileTexels)
      : scene_(scene),
        map_(initMap),
        cap_(cap),
        kept_(kept),
        store_(store),
        tileTexels_(tileTexels),
        tileArea_(static_cast<size_t>(tileTexels) * tileTexels),
        tilesOf_(cap.frames.size()),
        seenBits_(vis.offsets.size() - 1),
        texelPoint_(initMap.texelCount()),
        texelNormal_(initMap.texelCount()) {
    // For each frame, its tiles and its position in each tile's frame list.
    for (size_t t = 0; t + 1 < vis.offsets.size(); ++t)
      for (uint32_t k = vis.offsets[t]; k < vis.offsets[t + 1]; ++k)
        tilesOf_[vis.frames[k]].push_back({static_cast<uint32_t>(t), k - vis.offsets[t]});
    for (size_t t = 0; t + 1 < vis.offsets.size(); ++t) {
      framesOfTile_.push_back(vis.offsets[t + 1] - vis.offsets[t]);
      seenBits_[t].assign((tileArea_ * framesOfTile_[t] + 63) / 64, 0);
    }
    // Each texel's surface point and normal, computed once rather than once per frame.
    tbb::parallel_for(size_t{0}, initMap.texelCount(), [&](size_t t) {
      if (!initMap.valid(t)) return;
      bool geometric = false;
      texelPoint_[t] = initMap.point(scene.mesh(), t);
      texelNormal_[t] = initMap.normal(scene.mesh(), t, &geometric);
      if (geometric) fellBack_.fetch_add(1, std::memory_order_relaxed);
    });
  }

  // Calls add(texel, frame, radiance) for every observation of the texels in tile rows
  // [rows.first, rows.second) (all of them by default). Frames in order and, inside a frame, its
  // tiles in parallel: a texel (and its tile's bits) is only ever updated by one thread at a time,
  // so nothing needs atomics. The first pass traces, and must cover every row.
  void pass(const std::string& label, const std::function<void(size_t, uint32_t, const Color&)>& add,
            std::pair<int, int> rows = {0, std::numeric_limits<int>::max()}) {
    const int initRes = map_.resolution(), tilesPerSide = initRes / tileTexels_;
    const bool traced = passes_++ > 0;
    CHECK(traced || (rows.first == 0 && rows.second >= tilesPerSide));
    const auto tileAt = [&](int row) { return static_cast<uint32_t>(static_cast<size_t>(row) * tilesPerSide); };
    const uint32_t first = tileAt(rows.first), last = tileAt(std::min(rows.second, tilesPerSide));
    Progress progress(label, kept_.size());
    for (size_t k : kept_) {
      // A frame's tiles are in increasing order (the index lists frames tile by tile).
      const auto& tiles = tilesOf_[k];
      const auto begin = std::lower_bound(tiles.begin(), tiles.end(), std::pair<uint32_t, uint32_t>{first, 0});
      const auto end = std::lower_bound(begin, tiles.end(), std::pair<uint32_t, uint32_t>{last, 0});
      tbb::parallel_for(size_t{0}, static_cast<size_t>(end - begin), [&](size_t i) {
        const auto [tile, slot] = begin[static_cast<std::ptrdiff_t>(i)];
        std::vector<uint64_t>& bits = seenBits_[tile];
        const int tx = static_cast<int>(tile) % tilesPerSide, ty = static_cast<int>(tile) / tilesPerSide;
        for (int y = ty * tileTexels_; y < (ty + 1) * tileTexels_; ++y) {
          if (!ranks_.ownsChunk(static_cast<size_t>(y))) continue;
          for (int x = tx * tileTexels_; x < (tx + 1) * tileTexels_; ++x) {
            const size_t texel = static_cast<size_t>(y) * initRes + x;
            if (!map_.valid(texel)) continue;
            const size_t bit =
                (static_cast<size_t>(y - ty * tileTexels_) * tileTexels_ + (x - tx * tileTexels_)) + tileArea_ * slot;
            std::optional<Vec2> px;
            if (traced) {
              if (!(bits[bit / 64] >> (bit % 64) & 1)) continue;
              px = cap_.frames[k].camera.project(texelPoint_[texel]);
            } else {
              px = observe(scene_, cap_.frames[k].camera, texelPoint_[texel], texelNormal_[texel]);
            }
            if (!px) continue;
            const auto c = store_.bilinear(k, *px);
            if (!c) continue;
            if (!traced) bits[bit / 64] |= uint64_t{1} << (bit % 64);
            add(texel, static_cast<uint32_t>(k), *c);
          }
        }
      });
      progress.advance();
    }
  }
  size_t texelsWithGeometricNormal() const { return fellBack_.load(); }
  // The frames that see texel t's tile: the most observations it can have.
  size_t framesOfTexel(size_t t) const {
    const int res = map_.resolution(), tilesPerSide = res / tileTexels_;
    const size_t tile = (t / res / tileTexels_) * tilesPerSide + (t % res) / tileTexels_;
    return framesOfTile_[tile];
  }

 private:
  const Scene& scene_;
  const TexelMap& map_;
  const Capture& cap_;
  const std::vector<size_t>& kept_;
  const FrameStore& store_;
  const int tileTexels_;
  const size_t tileArea_;
  std::vector<std::vector<std::pair<uint32_t, uint32_t>>> tilesOf_;
  std::vector<uint32_t> framesOfTile_;
  std::vector<std::vector<uint64_t>> seenBits_;  // per tile: one bit per (texel, frame of the tile)
  std::vector<Vec3> texelPoint_, texelNormal_;
  std::atomic<size_t> fellBack_{0};
  int passes_ = 0;
  const Ranks& ranks_ = Ranks::world();
};

// Over MPI ranks: every sampled texel's observations, gathered by the rank owning its row
// (TexelObservations), on every rank, in the order one process holds them.
void shareSample(std::vector<std::vector<GainObservation>>& sampled, size_t stride, int resolution) {
  Ranks& ranks = Ranks::world();
  if (!ranks.distributed()) return;
  const auto owner = [&](size_t i) { return ranks.ownerOf(i * stride / static_cast<size_t>(resolution)); };
  std::vector<uint8_t> mine;
  const auto put = [&](const void* p, size_t n) {
    mine.insert(mine.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
  };
  for (size_t i = 0; i < sampled.size(); ++i) {
    if (owner(i) != ranks.rank()) continue;
    const uint64_t n = sampled[i].size();
    put(&n, sizeof n);
    put(sampled[i].data(), n * sizeof(GainObservation));
  }
  const std::vector<std::vector<uint8_t>> all = ranks.allGather(mine);
  std::vector<size_t> at(all.size(), 0);
  for (size_t i = 0; i < sampled.size(); ++i) {
    const int r = owner(i);
    if (r == ranks.rank()) continue;
    const std::vector<uint8_t>& bytes = all[static_cast<size_t>(r)];
    uint64_t n = 0;
    CHECK(at[r] + sizeof n <= bytes.size());
    std::memcpy(&n, bytes.data() + at[r], sizeof n);
    at[r] += sizeof n;
    CHECK(at[r] + n * sizeof(GainObservation) <= bytes.size());
    sampled[i].resize(n);
    if (n > 0)  // an empty vector's data() may be null, which memcpy must not get
      std::memcpy(static_cast<void*>(sampled[i].data()), bytes.data() + at[r], n * sizeof(GainObservation));
    at[r] += n * sizeof(GainObservation);
  }
  for (size_t r = 0; r < all.size(); ++r) CHECK(static_cast<int>(r) == ranks.rank() || at[r] == all[r].size());
}

// Frame gains from the frames' agreement on a regular sample of texels (photometric_consistency.h),
// written to frame_gains.json: what the fit starts its frame gains from, and a check of recorded
// exposures.
constexpr size_t kConsistencyTexels = 65536;
size_t defaultGainStride(size_t texels) { return std::max<size_t>(1, texels / kConsistencyTexels); }
ConsistencyGains consistencyGains(TexelObservations& observations, const TexelMap& initMap, const FrameStore& store,
                                  const std::vector<size_t>& kept, size_t stride, const fs::path& work) {
  std::vector<std::vector<GainObservation>> sampled((initMap.texelCount() + stride - 1) / stride);
  // Each sampled texel holds room for every frame of its tile, its most, so that what the sample
  // holds is what the memory plan counts (growth by doubling would hold up to twice what it keeps).
  for (size_t i = 0; i < sampled.size(); ++i)
    if (initMap.valid(i * stride)) sampled[i].reserve(observations.framesOfTexel(i * stride));
  observations.pass("frame gains", [&](size_t t, uint32_t f, const Color& c) {
    const FrameStats& s = store.stats(f);
    if (t % stride == 0 && (c > s.clipLow).all() && (c < s.clipHigh).all() && (c > 0.0f).all())
      sampled[t / stride].push_back({f, c});
  });
  shareSample(sampled, stride, initMap.resolution());
  const std::vector<uint32_t> keptFrames(kept.begin(), kept.end());
  const ConsistencyGains g = solveConsistencyGains(sampled, store.frameCount(), keptFrames);
  if (Ranks::world().root()) writeConsistencyGains(work / "frame_gains.json", g, keptFrames);
  return g;
}

// How the frames agree on each texel (agreement.exr, at the init resolution), each observation's
// deviation from the texel's init value (the median) measured by observationDeviation. R: the mean
// deviation of the texel's unclipped observations; G: the share of them beyond a factor
// kAgreementRatio (a misregistered edge, an object the mesh lacks, a highlight);
// B: the share of all its observations clipped (a channel at the frame's ceiling, or every channel
// at its floor). 0 where no frame saw the texel. Returns medians over observed texels (prepare.json).
Json agreementPass(TexelObservations& observations, const FrameStore& store, const Image& init,
                   const std::vector<uint32_t>& coverage, const std::function<Color(uint32_t, const Color&)>& radiance,
                   const fs::path& file) {
  const size_t texels = coverage.size();
  std::vector<float> deviation(texels, 0.0f);
  std::vector<uint32_t> disagree(texels, 0), clipped(texels, 0), unclipped(texels, 0);
  const float threshold = std::log(kAgreementRatio);
  observations.pass("agreement", [&](size_t t, uint32_t f, const Color& c) {
    const FrameStats& s = store.stats(f);
    if ((c >= s.clipHigh).any() || (c <= s.clipLow).all()) {
      ++clipped[t];
      return;
    }
    const Color median = init.at(static_cast<int>(t % init.width), static_cast<int>(t / init.width));
    const float d = observationDeviation(radiance(f, c), median);
    deviation[t] += d, disagree[t] += d > threshold, ++unclipped[t];
  });
  Ranks& ranks = Ranks::world();
  const size_t width = static_cast<size_t>(init.width);
  Image out(init.width, init.height);
  for (size_t t = 0; t < texels; ++t) {
    if (!coverage[t] || !ranks.ownsChunk(t / width)) continue;  // another rank's row
    const float spread = unclipped[t] ? deviation[t] / unclipped[t] : 0.0f;
    const float share = unclipped[t] ? static_cast<float>(disagree[t]) / unclipped[t] : 0.0f;
    out.set(static_cast<int>(t % width), static_cast<int>(t / width),
            Color(spread, share, static_cast<float>(clipped[t]) / (clipped[t] + unclipped[t])));
  }
  ranks.shareChunks(out.rgb, 3 * width);
  std::vector<float> spreads, shares;
  for (size_t t = 0; t < texels; ++t) {
    if (!coverage[t]) continue;
    spreads.push_back(out.rgb[3 * t]), shares.push_back(out.rgb[3 * t + 1]);
  }
  if (ranks.root()) writeExr(file, out);
  return {{"agreement_ratio", kAgreementRatio},
          {"median_log_spread", medianOf(spreads)},
          {"median_share_disagreeing", medianOf(shares)}};
}

// Initial albedo: the streaming median (or mean) of each texel's observed radiance, and how many
// observations each texel had (coverage).
Json initPhase(const Scene& scene, const TexelMap& initMap, const Capture& cap, const std::vector<size_t>& kept,
               const InitPhasePlan& plan, const fs::path& work, const PrepareOptions& o) {
  const TriangleMesh& mesh = scene.mesh();
  const int initRes = initMap.resolution();
  const size_t skippedBefore = scene.skippedRays();
  const VisibilityIndex vis = VisibilityIndex::read(work / "visibility.bin", cap.frames.size());
  const FrameStore store(work / "frames.bin");
  if (store.frameCount() != cap.frames.size())
    fail("{}: holds {} frames, the capture has {} (rerun with --force)", (work / "frames.bin").string(),
         store.frameCount(), cap.frames.size());
  TexelObservations observations(scene, initMap, cap, kept, vis, store, o.tileTexels);
  const size_t texels = initMap.texelCount();
  std::vector<uint32_t> coverage(texels, 0);
  const ConsistencyGains gains = consistencyGains(observations, initMap, store, kept, plan.gainStride, work);
  // The init averages radiance: frames whose gains the fit estimates are divided by them first.
  const bool corrected = resolveFrameGains(FrameGainMode::Auto, cap.frames, store,
                                           std::vector<uint32_t>(kept.begin(), kept.end())) != FrameGainMode::None;
  const auto radiance = [&](uint32_t f, const Color& c) { return corrected ? Color(c / gains.gain[f]) : c; };
  releaseFreeHeap();  // the gain sample's many small arrays, freed inside the heap: not held through the median
  Image albedo(initRes, initRes), cov(initRes, initRes);
  size_t valid = 0, unobserved = 0;
  std::vector<Eigen::Array4d> objectMean(mesh.objectCount, Eigen::Array4d::Zero());
  // Band by band of tile rows (the memory plan's bands): a band's texels are the contiguous range
  // [first, first + count), and each texel's statistic is the same whichever band it is in.
  const int tileRows = initRes / o.tileTexels;
  const int rowsPerBand = plan.rowsPerBand;
  const size_t bandTexels = static_cast<size_t>(rowsPerBand) * o.tileTexels * initRes;
  std::optional<MedianSketch> sketch;  // one for every band, freed before the agreement pass
  if (o.init == InitStatistic::Median) sketch.emplace(bandTexels);
  std::vector<Eigen::Array3d> sum(o.init == InitStatistic::Mean ? bandTexels : 0);
  for (int row = 0; row < tileRows; row += rowsPerBand) {
    const std::pair<int, int> rows{row, std::min(row + rowsPerBand, tileRows)};
    const size_t first = static_cast<size_t>(rows.first) * o.tileTexels * initRes;
    const size_t count = static_cast<size_t>(rows.second - rows.first) * o.tileTexels * initRes;
    const std::string band = plan.bands > 1 ? fmt::format(", tile rows {}-{}", rows.first, rows.second - 1) : "";
    std::function<Color(size_t)> statistic;
    if (sketch && row > 0) sketch->restart();
    std::fill(sum.begin(), sum.end(), Eigen::Array3d::Zero());
    if (sketch) {
      observations.pass(
          "median (coarse" + band + ")",
          [&](size_t t, uint32_t f, const Color& c) { sketch->addCoarse(t - first, radiance(f, c)); }, rows);
      sketch->startFine();
      observations.pass(
          "median (fine" + band + ")",
          [&](size_t t, uint32_t f, const Color& c) { sketch->addFine(t - first, radiance(f, c)); }, rows);
      for (size_t t = first; t < first + count; ++t) coverage[t] = sketch->count(t - first);
      statistic = [&](size_t t) { return sketch->median(t - first); };
    } else {
      observations.pass(
          "mean" + band,
          [&](size_t t, uint32_t f, const Color& c) {
            sum[t - first] += radiance(f, c).cast<double>(), ++coverage[t];
          },
          rows);
      statistic = [&](size_t t) { return Color((sum[t - first] / coverage[t]).cast<float>()); };
    }
    for (size_t t = first; t < first + count; ++t)
      if (initMap.valid(t) && coverage[t] > 0)
        albedo.set(static_cast<int>(t % initRes), static_cast<int>(t / initRes), statistic(t));
  }
  sketch.reset();
  std::vector<Eigen::Array3d>().swap(sum);
  // Every rank's rows (TexelObservations splits them) on every rank.
  Ranks& ranks = Ranks::world();
  ranks.shareChunks(albedo.rgb, 3 * static_cast<size_t>(initRes));
  ranks.shareChunks(coverage, static_cast<size_t>(initRes));
  for (size_t t = 0; t < texels; ++t) {
    if (!initMap.valid(t)) continue;
    ++valid;
    cov.set(static_cast<int>(t % initRes), static_cast<int>(t / initRes),
            Color::Constant(static_cast<float>(coverage[t])));
    if (coverage[t] == 0) {
      ++unobserved;
      continue;
    }
    const Eigen::Array3d vd = albedo.at(static_cast<int>(t % initRes), static_cast<int>(t / initRes)).cast<double>();
    objectMean[mesh.faceObject[initMap.triangle(t)]] += Eigen::Array4d(vd[0], vd[1], vd[2], 1.0);
  }
  // Texels no frame saw start from their object's average (or mid-grey).
  for (size_t t = 0; t < texels; ++t) {
    if (!initMap.valid(t) || coverage[t] > 0) continue;
    const Eigen::Array4d& m = objectMean[mesh.faceObject[initMap.triangle(t)]];
    albedo.set(static_cast<int>(t % initRes), static_cast<int>(t / initRes),
               m[3] > 0 ? Color((m.head<3>() / m[3]).cast<float>()) : Color::Constant(0.5f));
  }
  const Json agreementSummary = agreementPass(observations, store, albedo, coverage, radiance, work / "agreement.exr");
  if (ranks.root()) {
    writeExr(work / "albedo_init.exr", albedo);
    writePng(work / "albedo_init.png", albedo);  // preview
    writeExr(work / "coverage.exr", cov);
    writePng(work / "coverage.png", falseColour(coverage, initRes));
  }
  const double fraction = valid ? double(unobserved) / valid : 0.0;
  spdlog::info("init: {} valid texels at {}^2, {:.2f}% never observed", valid, initRes, 100 * fraction);
  return Json{{"resolution", initRes},
              {"statistic", o.init == InitStatistic::Median ? "median" : "mean"},
              {"valid_texels", valid},
              {"unobserved_texels", unobserved},
              {"fraction_unobserved", fraction},
              {"texels_geometric_normal", observations.texelsWithGeometricNormal()},
              {"agreement", agreementSummary},
              {"skipped_rays", ranks.sum(scene.skippedRays() - skippedBefore)}};
}

// The init phase's plan (product/prepare_memory.h) from what the process holds now, with the
// heap's free pages returned first (the atlas phase's, reused by the init phase's arrays).
InitPhasePlan planInit(const TexelMap& initMap, const Capture& cap, const std::vector<size_t>& kept,
                       const fs::path& work, const PrepareOptions& o) {
  const size_t texels = initMap.texelCount();
  InitPhaseSize size;
  size.resolution = initMap.resolution();
  size.median = o.init == InitStatistic::Median;
  size.tileTexels = static_cast<size_t>(o.tileTexels);
  size.tileRows = initMap.resolution() / o.tileTexels;
  size.defaultGainStride = defaultGainStride(texels);
  size.keptFrames = kept.size();
  if (o.memoryBudgetBytes <= 0) return planInitPhase(0, size);
  const VisibilityIndex vis = VisibilityIndex::read(work / "visibility.bin", cap.frames.size());
  size.visibilityEntries = vis.frames.size();
  size.frameCacheBytes = static_cast<double>(fileSize(work / "frames.bin"));
  const int tilesPerSide = size.tileRows, res = initMap.resolution();
  for (int t = 0; t + 1 < static_cast<int>(vis.offsets.size()); ++t) {
    const double frames = vis.offsets[t + 1] - vis.offsets[t];
    if (frames == 0) continue;
    size_t validTexels = 0;
    const int tx = t % tilesPerSide, ty = t / tilesPerSide;
    for (int y = ty * o.tileTexels; y < (ty + 1) * o.tileTexels; ++y)
      for (int x = tx * o.tileTexels; x < (tx + 1) * o.tileTexels; ++x)
        validTexels += initMap.valid(static_cast<size_t>(y) * res + x);
    size.sampleObservationsAtStride1 += frames * static_cast<double>(validTexels);
  }
  releaseFreeHeap();
  size.heldBytes = currentRssMiB() * (1 << 20);
  const InitPhasePlan plan = planInitPhase(o.memoryBudgetBytes, size);
  spdlog::info("prepare: memory budget {}: the init phase is predicted at {} (median in {} band(s), one texel in {} "
               "sampled for the frame gains)",
               formatBytes(o.memoryBudgetBytes), formatBytes(plan.peakBytes()), plan.bands, plan.gainStride);
  return plan;
}

}  // namespace

void applyPreparedResponse(const Json& prepare, std::vector<Frame>& frames) {
  if (!prepare.contains("response")) return;
  const Json& r = prepare["response"];
  const Response response =
      Response::parse(r.at("spec").get<std::string>(), r.at("dir").get<std::string>(), "prepare --response");
  for (Frame& f : frames) f.response = response;
}

fs::path capturePreparedIn(const fs::path& work) {
  const fs::path file = work / "prepare.json";
  const Json report = readJson(file);
  if (!report.is_object() || !report.contains("capture") || !report["capture"].is_string())
    fail("{}: no 'capture' folder named; rerun `relume prepare`", file.string());
  return report["capture"].get<std::string>();
}

PrepareSummary prepareCapture(const fs::path& capture, const fs::path& work, const PrepareOptions& o) {
  Timer total;
  // Over MPI ranks the root decides which phases run and writes every file; the frames and the
  // init phases are split between the ranks, the others run on the root (docs/design/distributed.md).
  Ranks& ranks = Ranks::world();
  const auto rootJson = [&](const Json& j) { return ranks.distributed() ? Json::parse(ranks.rootString(j.dump())) : j; };
  requireDirectory(capture, "a capture folder");
  if (ranks.root()) {
    createDirectories(work);
    if (const size_t stale = removeStaleTemporaries(work))
      spdlog::info("prepare: removed {} temporaries of killed runs", stale);
  }
  const fs::path meshPath = findCaptureMesh(capture);
  Capture cap = readCapture(capture);
  Json report = ranks.root() ? previousReport(work / "prepare.json", o.force) : Json::object();
  const Json rootReport = rootJson(report);
  if (!ranks.root()) report = rootReport;
  report.erase("response");
  if (!o.response.empty()) report["response"] = {{"spec", o.response}, {"dir", fs::current_path().string()}};
  applyPreparedResponse(report, cap.frames);
  const Json reportBefore = report;
  const std::vector<DuplicateFrame> duplicates = findDuplicateFrames(cap);  // a conflict fails before any work
  Json phases = report.value("phases", Json::object());
  const int initRes = o.resolutions.front();
  if (initRes % o.tileTexels != 0)
    fail("prepare: init resolution {} is not a multiple of the tile size {}", initRes, o.tileTexels);
  for (int r : o.resolutions)
    if (r < o.atlas.gutterResolution || r % o.atlas.gutterResolution != 0)
      fail("prepare: resolution {} must be a multiple of the atlas gutter resolution {}", r, o.atlas.gutterResolution);
  if (o.memoryBudgetBytes > 0) {  // refused before any work when even the leanest plan cannot fit
    double frameCache = 0;
    const auto stored = [&](int side) { return std::ceil(static_cast<double>(side) / o.downscale); };
    for (const Frame& f : cap.frames) frameCache += 6.0 * stored(f.camera.width) * stored(f.camera.height);
    checkPrepareBudgetUpFront(o.memoryBudgetBytes, loadMesh(meshPath).triangles.size(), frameCache,
                              static_cast<size_t>(initRes) * initRes);
  }

  // A phase is current when its fingerprint (inputs + options + the previous phase) is unchanged.
  // A phase `split` between the ranks runs on every rank (a collective), any other on the root.
  enum class Runs { OnRoot, Split };
  auto runPhase = [&](const char* name, const std::string& fingerprint, const std::vector<fs::path>& outputs,
                      Runs runs, const std::function<Json()>& body) {
    bool current = !o.force && phases.contains(name) && phases[name].value("fingerprint", "") == fingerprint;
    for (const fs::path& out : outputs) current = current && pathExists(out);
    if (ranks.rootValue(current ? 1 : 0) != 0) {
      spdlog::info("prepare: {} is up to date", name);
      return;
    }
    Timer t;
    Json result = runs == Runs::Split || ranks.root() ? body() : Json::object();
    result["fingerprint"] = fingerprint;
    result["seconds"] = t.seconds();
    result["peak_rss_mib_so_far"] = peakRssMiB();  // the run's peak at the phase's end: which phase raised it
    // The root's record, sent once its files are in place: the other ranks read them next.
    if (ranks.root()) {
      phases[name] = result;
      report["phases"] = phases;
      writeJson(work / "prepare.json", report);  // after each phase: an interrupted run keeps its progress
    }
    const Json rootRecord = rootJson(phases[name]);
    if (!ranks.root()) phases[name] = rootRecord, report["phases"] = phases;
    spdlog::info("prepare: {} done in {:.1f}s (peak RSS so far {:.0f} MiB)", name, t.seconds(), peakRssMiB());
  };

  // Frames: convert, then filter.
  std::vector<fs::path> imagePaths = cap.files;
  for (const Frame& f : cap.frames) imagePaths.push_back(f.image);
  // "frames3": the frame cache's format (with clip thresholds) and the filter that drops
  // duplicates, so work folders made before them are converted and filtered again.
  std::string responses;
  for (const Frame& f : cap.frames) responses += f.response.fingerprint() + ";";
  const std::string framesPrint =
      fingerprintOf(imagePaths, fmt::format("frames3 {} {} {} {} {} {} {}", o.maxOverexposed, o.maxUnderexposed,
                                            o.maxSpeed, o.maxAngularSpeed, o.downscale, o.encodingClips, responses));
  runPhase("frames", framesPrint, {work / "frames.bin"}, Runs::Split,
           [&] { return framesPhase(cap, duplicates, work, o); });
  const std::vector<size_t> kept = jsonIntegers<size_t>(phases["frames"]["kept"], 0, cap.frames.size() - 1,
                                                        (work / "prepare.json").string(), "kept");
  if (kept.empty()) fail("prepare: every frame was dropped (see {})", (work / "prepare.json").string());

  // Segmentation, when the objects are computed.
  const bool computeObjects = o.segmentation == SegmentationMode::Computed ||
                              (o.segmentation == SegmentationMode::Auto && loadMesh(meshPath).objectCount == 1);
  std::string segmentationPrint = "given";
  if (computeObjects) {
    const SegmentationOptions& so = o.segmentationOptions;
    // "segmentation1": the segmentation's version, so a changed method recomputes it.
    segmentationPrint = fingerprintOf(
        {meshPath}, fmt::format("segmentation1 {} {} {} {} {} {} {} {} {} {} {} {} {}", framesPrint, so.creaseDegrees,
                                so.regionCreaseDegrees,
                                so.edgeContrast, so.regionContrast, so.significance, so.clipSplit, so.minAreaFraction,
                                so.keepBrighter, o.faceAppearance.maxFrames, o.faceAppearance.radianceFloor,
                                o.faceAppearance.minLogSpread, o.faceAppearance.planeTolerance));
    runPhase("segmentation", segmentationPrint, {work / "segments.bin", work / "objects.json"}, Runs::OnRoot,
             [&] { return segmentationPhase(meshPath, cap, kept, work, o); });
  } else if (phases.contains("segmentation")) {
    phases.erase("segmentation");
    report["phases"] = phases;
    if (ranks.root()) {
      removeFile(work / "segments.bin");
      removeFile(work / "objects.json");
    }
  }

  // Atlas.
  // "atlas2": the charting/packing version, so work folders made by an older atlas are re-charted.
  const std::string atlasPrint =
      fingerprintOf({meshPath}, fmt::format("atlas2 {} {} {} {} {}", o.atlas.gutterResolution, o.atlas.gutterTexels,
                                            o.atlas.coneDegrees, o.atlas.planarDegrees, segmentationPrint));
  const std::optional<fs::path> segments =
      computeObjects ? std::optional<fs::path>(work / "segments.bin") : std::nullopt;
  runPhase("atlas", atlasPrint, {work / "atlas_mesh.ply"}, Runs::OnRoot,
           [&] { return atlasPhase(capture, meshPath, work, o, segments); });
  const TriangleMesh mesh = loadMesh(work / "atlas_mesh.ply");
  const Scene scene(mesh);

  // Visibility index over tiles of the init resolution.
  const TexelMap initMap(mesh, initRes);
  const std::string visPrint = fingerprintOf(
      {}, fmt::format("vis {} {} {} {} {}", atlasPrint, framesPrint, initRes, o.tileTexels, o.samplesPerTile));
  runPhase("visibility", visPrint, {work / "visibility.bin"}, Runs::OnRoot,
           [&] { return visibilityPhase(scene, initMap, cap, kept, work, o); });

  // Initial albedo (streaming median of observed radiance) and coverage, planned to the budget
  // when the phase runs. "init2": with the frame gains of the frames' agreement. The budget is an
  // input: the plan it leads to follows what the process holds, which differs between runs, and a
  // sparser gain sample is a different result.
  const std::string budget = o.memoryBudgetBytes > 0 ? fmt::format(" budget {}", o.memoryBudgetBytes) : "";
  const std::string initPrint =
      fingerprintOf({}, fmt::format("init2 {} {}{}", visPrint, static_cast<int>(o.init), budget));
  runPhase("init", initPrint,
           {work / "albedo_init.exr", work / "coverage.exr", work / "coverage.png", work / "frame_gains.json",
            work / "agreement.exr"},
           Runs::Split, [&] {
             // The root's plan: the ranks' resident sets differ, and the gain sample's stride is a result.
             InitPhasePlan plan = ranks.root() ? planInit(initMap, cap, kept, work, o) : InitPhasePlan{};
             plan.rowsPerBand = static_cast<int>(ranks.rootValue(plan.rowsPerBand));
             plan.bands = static_cast<int>(ranks.rootValue(plan.bands));
             plan.gainStride = static_cast<size_t>(ranks.rootValue(static_cast<double>(plan.gainStride)));
             Json result = initPhase(scene, initMap, cap, kept, plan, work, o);
             if (o.memoryBudgetBytes > 0) result["memory_budget"] = plan.toJson();
             return result;
           });

  PrepareSummary s;
  s.frames = cap.frames.size();
  s.keptFrames = kept.size();
  s.triangles = mesh.triangles.size();
  s.fractionUnobserved = phases["init"].value("fraction_unobserved", 0.0);
  s.seconds = total.seconds();
  report["capture"] = absolutePath(capture).string();
  report["resolutions"] = o.resolutions;
  report["texel_map_bytes_per_texel"] = sizeof(uint32_t);
  // Timings describe the last run that did something: an up-to-date folder (even a read-only one)
  // is left untouched.
  if (report != reportBefore && ranks.root()) {
    report["peak_rss_mib"] = peakRssMiB();
    report["seconds_total_last_run"] = s.seconds;
    writeJson(work / "prepare.json", report);
  }
  return s;
}

}  // namespace relume
