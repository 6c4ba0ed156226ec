#include "scenes/imperfections.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <numeric>

#include <fmt/ranges.h>
#include <tbb/parallel_for.h>

#include "core/check.h"
#include "core/error.h"
#include "core/random_streams.h"
#include "core/rng.h"
#include "core/warp.h"
#include "io/image.h"
#include "scene/mesh.h"
#include "scene/scene.h"

namespace relume {
namespace {

constexpr const char* kKeys =
    "pose, bracket, wb, exposure-drift, noise, ldr, mesh, segmentation, missing, absent, unseen";

// Bounds beyond which a value is a typo, not a camera (SI units).
constexpr double kMaxPoseMetres = 1.0, kMaxPoseDegrees = 45.0;
constexpr double kMaxStops = 20.0;
constexpr size_t kMaxBracket = 16;
constexpr double kMaxLogGainSigma = 1.0;
constexpr double kMinPhotons = 1.0, kMaxPhotons = 1e12, kMaxReadSigma = 1.0;
constexpr double kMaxMeshMetres = 0.5;
constexpr double kMaxMissingPercent = 95.0;
// Below this many expected photons the shot noise is drawn exactly (Poisson), above from N(l, l).
constexpr double kExactPoissonBelow = 64.0;
// Coincident vertices are found on this grid (metres), as in makeScanLikeRoom.
constexpr float kVertexGrid = 1e-4f;

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

std::vector<std::string_view> split(std::string_view s, char sep) {
  std::vector<std::string_view> parts;
  for (size_t start = 0;;) {
    const size_t end = s.find(sep, start);
    parts.push_back(trim(s.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start)));
    if (end == std::string_view::npos) return parts;
    start = end + 1;
  }
}

// A finite decimal number filling the whole token (no sign '+', no hex, no inf/nan).
std::optional<double> number(std::string_view token) {
  double v = 0;
  const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (token.empty() || ec != std::errc() || end != token.data() + token.size() || !std::isfinite(v))
    return std::nullopt;
  return v;
}

// `unit` (with its space) ends the bounds of the message: "must be in [0, 100] cm".
double numberIn(std::string_view key, std::string_view what, std::string_view token, double lo, double hi,
                std::string_view unit = "") {
  const auto v = number(token);
  if (!v) fail("imperfection '{}': {} '{}' is not a number", key, what, token);
  if (!(*v >= lo && *v <= hi))
    fail("imperfection '{}': {} is {}, must be in [{:g}, {:g}]{}", key, what, *v, lo, hi, unit);
  return *v;
}

// "<number><unit>", unit one of `units`, each with its factor to SI; bounded in SI.
template <typename Q>
Q quantity(std::string_view key, std::string_view what, std::string_view token,
           std::initializer_list<std::pair<const char*, double>> units, double hiSi, std::string_view allowed) {
  for (const auto& [unit, factor] : units) {
    const std::string_view u(unit);
    if (token.size() <= u.size() || token.substr(token.size() - u.size()) != u) continue;
    const std::string_view digits = token.substr(0, token.size() - u.size());
    if (!number(digits)) break;
    const double v = numberIn(key, what, digits, 0.0, hiSi / factor, fmt::format(" {}", u));
    return Q{v, std::string(u)};
  }
  if (number(token)) fail("imperfection '{}': {} '{}' needs a unit ({})", key, what, token, allowed);
  fail("imperfection '{}': {} '{}' must be a number with a unit ({})", key, what, token, allowed);
}

std::vector<std::string_view> values(std::string_view key, std::string_view value, size_t lo, size_t hi,
                                     std::string_view form) {
  const auto parts = split(value, ',');
  if (parts.size() < lo || parts.size() > hi) fail("imperfection '{}': expected {}, got '{}'", key, form, value);
  for (std::string_view p : parts)
    if (p.empty()) fail("imperfection '{}': empty number in '{}' (expected {})", key, value, form);
  return parts;
}

void parseItem(ImperfectionSpec& s, std::string_view key, std::string_view value) {
  if (key == "pose") {
    const auto v = values(key, value, 2, 2, "D,A: a distance (mm, cm, m) and an angle (deg, rad), e.g. 1cm,0.3deg");
    s.pose = PoseError{quantity<Length>(key, "translation", v[0], {{"mm", 1e-3}, {"cm", 1e-2}, {"m", 1.0}},
                                        kMaxPoseMetres, "mm, cm or m"),
                       quantity<Angle>(key, "rotation", v[1], {{"deg", kPi / 180}, {"rad", 1.0}},
                                       kMaxPoseDegrees * kPi / 180, "deg or rad")};
  } else if (key == "bracket") {
    const auto v = values(key, value, 1, kMaxBracket, fmt::format("1 to {} stops separated by ','", kMaxBracket));
    for (std::string_view e : v) s.bracketStops.push_back(numberIn(key, "stop", e, -kMaxStops, kMaxStops));
  } else if (key == "wb") {
    s.whiteBalance = numberIn(key, "log-gain sigma", values(key, value, 1, 1, "one sigma")[0], 0, kMaxLogGainSigma);
  } else if (key == "exposure-drift") {
    s.exposureDrift = numberIn(key, "log-gain sigma", values(key, value, 1, 1, "one sigma")[0], 0, kMaxLogGainSigma);
  } else if (key == "noise") {
    const auto v = values(key, value, 2, 2, "F,R: photons at radiance 1 and read-noise sigma, e.g. 1000,0.002");
    s.noise = SensorNoise{numberIn(key, "photons", v[0], kMinPhotons, kMaxPhotons),
                          numberIn(key, "read-noise sigma", v[1], 0, kMaxReadSigma)};
  } else if (key == "ldr") {
    const auto bits = number(values(key, value, 1, 1, "8 or 16")[0]);
    if (!bits || (*bits != 8 && *bits != 16)) fail("imperfection 'ldr': bit depth '{}' must be 8 or 16", value);
    s.ldrBits = static_cast<int>(*bits);
  } else if (key == "mesh") {
    s.meshNoise = quantity<Length>(key, "displacement", values(key, value, 1, 1, "one distance")[0],
                                   {{"mm", 1e-3}, {"cm", 1e-2}, {"m", 1.0}}, kMaxMeshMetres, "mm, cm or m");
  } else if (key == "segmentation") {
    if (value != "none") fail("imperfection 'segmentation': '{}' is not allowed (only 'none')", value);
    s.segmentation = false;
  } else if (key == "missing") {
    s.missingPercent =
        numberIn(key, "percentage", values(key, value, 1, 1, "one percentage")[0], 0, kMaxMissingPercent);
  } else if (key == "absent") {
    if (value.empty() || value.find_first_of(", ") != std::string_view::npos)
      fail("imperfection 'absent': '{}' must be one object's name", value);
    s.absentObject = std::string(value);
  } else if (key == "unseen") {
    if (value.find_first_of(", ") != std::string_view::npos)
      fail("imperfection 'unseen': '{}' must be one object's name", value);
    s.unseenObject = std::string(value);
  } else {
    fail("imperfection '{}' is unknown (keys: {})", key, kKeys);
  }
}

// Box-Muller: one standard normal draw from two uniforms.
double gaussian(Pcg32& rng) {
  const double u1 = 1.0 - rng.next1D(), u2 = rng.next1D();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

// Poisson(mean): exact (Knuth's product of uniforms) for small means, N(mean, mean) above.
double poisson(Pcg32& rng, double mean) {
  if (mean <= 0) return 0;
  if (mean >= kExactPoissonBelow) return mean + std::sqrt(mean) * gaussian(rng);
  const double limit = std::exp(-mean);
  double product = 1.0 - rng.next1D();
  int k = 0;
  while (product > limit) {
    product *= 1.0 - rng.next1D();
    ++k;
  }
  return k;
}

Pcg32 frameStream(uint64_t seed, RandomStream stream, int frame) {
  return Pcg32(hashTuple({seed, streamTag(stream), static_cast<uint64_t>(frame)}));
}

// The written pose: moved by exactly D in a uniformly random direction, turned by exactly A about a
// uniformly random axis through the camera centre.
Camera perturbPose(const Camera& truth, const PoseError& error, Pcg32& rng) {
  const Vec3 direction = squareToUniformSphere(rng.next2D());
  const Vec3 axis = squareToUniformSphere(rng.next2D());
  Camera c = truth;
  c.position = (truth.position.cast<double>() + error.translation.metres() * direction.cast<double>()).cast<float>();
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(error.rotation.radians(), axis.cast<double>()).toRotationMatrix();
  c.rotation = (turn * truth.rotation.cast<double>()).cast<float>();
  return c;
}

// round(P N / 100) frame indices, chosen by a partial Fisher-Yates shuffle.
std::vector<int> leftOutFrames(double percent, int frames, uint64_t seed) {
  const int count = static_cast<int>(std::lround(percent * frames / 100.0));
  if (count >= frames) fail("imperfection 'missing={}' leaves none of the {} training frames", percent, frames);
  std::vector<int> order(frames);
  std::iota(order.begin(), order.end(), 0);
  Pcg32 rng(hashTuple({seed, streamTag(RandomStream::SynthMissingFrames)}));
  for (int j = 0; j < count; ++j) std::swap(order[j], order[j + rng.nextU32() % static_cast<uint32_t>(frames - j)]);
  order.resize(count);
  std::sort(order.begin(), order.end());
  return order;
}

}  // namespace

double Length::metres() const { return value * (unit == "mm" ? 1e-3 : unit == "cm" ? 1e-2 : 1.0); }
double Angle::radians() const { return unit == "deg" ? value * kPi / 180.0 : value; }

ImperfectionSpec parseImperfections(std::string_view spec) {
  ImperfectionSpec s;
  if (trim(spec).empty()) return s;
  // Errors quote the spec: a control character (a newline) would break them over lines.
  const auto control = std::find_if(spec.begin(), spec.end(), [](char c) { return c >= 0 && c < 0x20 && c != '\t'; });
  if (control != spec.end())
    fail("imperfection spec has control character {:#04x} at byte {} (printable KEY=VALUE items separated by ';')",
         static_cast<int>(*control), control - spec.begin());
  std::vector<std::string_view> seen;
  for (std::string_view item : split(spec, ';')) {
    if (item.empty()) fail("imperfection spec '{}' has an empty item (KEY=VALUE items separated by ';')", spec);
    const size_t eq = item.find('=');
    if (eq == std::string_view::npos) fail("imperfection '{}' is not KEY=VALUE (keys: {})", item, kKeys);
    const std::string_view key = trim(item.substr(0, eq)), value = trim(item.substr(eq + 1));
    if (std::find(seen.begin(), seen.end(), key) != seen.end()) fail("imperfection '{}' is given twice", key);
    seen.push_back(key);
    if (value.empty() && !key.empty()) fail("imperfection '{}' has an empty value", key);
    parseItem(s, key, value);
  }
  return s;
}

std::string toString(const ImperfectionSpec& s) {
  std::vector<std::string> items;
  if (s.pose)
    items.push_back(fmt::format("pose={}{},{}{}", s.pose->translation.value, s.pose->translation.unit,
                                s.pose->rotation.value, s.pose->rotation.unit));
  if (!s.bracketStops.empty()) items.push_back(fmt::format("bracket={}", fmt::join(s.bracketStops, ",")));
  if (s.whiteBalance) items.push_back(fmt::format("wb={}", *s.whiteBalance));
  if (s.exposureDrift) items.push_back(fmt::format("exposure-drift={}", *s.exposureDrift));
  if (s.noise) items.push_back(fmt::format("noise={},{}", s.noise->photons, s.noise->readSigma));
  if (s.ldrBits) items.push_back(fmt::format("ldr={}", *s.ldrBits));
  if (s.meshNoise) items.push_back(fmt::format("mesh={}{}", s.meshNoise->value, s.meshNoise->unit));
  if (!s.segmentation) items.push_back("segmentation=none");
  if (s.missingPercent) items.push_back(fmt::format("missing={}", *s.missingPercent));
  if (!s.absentObject.empty()) items.push_back("absent=" + s.absentObject);
  if (!s.unseenObject.empty()) items.push_back("unseen=" + s.unseenObject);
  return fmt::format("{}", fmt::join(items, ";"));
}

int32_t namedObject(std::string_view key, const std::string& name, const std::vector<std::string>& objectNames) {
  const auto named = std::find(objectNames.begin(), objectNames.end(), name);
  if (named == objectNames.end())
    fail("imperfection '{}': the scene has no object '{}' (objects: {})", key, name, fmt::join(objectNames, ", "));
  return static_cast<int32_t>(named - objectNames.begin());
}

std::vector<uint8_t> camerasShowing(const MeshData& mesh, int32_t object, const std::vector<Camera>& cameras) {
  const Scene scene(buildMesh(mesh, "the capture's mesh"));
  std::vector<uint8_t> shows(cameras.size(), 0);
  tbb::parallel_for(size_t{0}, cameras.size(), [&](size_t i) {
    const Camera& c = cameras[i];
    for (int y = 0; y < c.height && !shows[i]; ++y)
      for (int x = 0; x < c.width && !shows[i]; ++x)
        if (const auto dir = c.rayDirection(Vec2(x + 0.5f, y + 0.5f)))
          if (const auto hit = scene.intersect(c.position, *dir)) shows[i] = hit->object == object;
  });
  return shows;
}

std::vector<FrameImperfection> planFrameImperfections(const ImperfectionSpec& spec, const std::vector<Camera>& walk,
                                                      uint64_t seed, const std::vector<uint8_t>& showsUnseen) {
  const int n = static_cast<int>(walk.size());
  CHECK(showsUnseen.empty() || showsUnseen.size() == walk.size());
  const std::vector<int> leftOut =
      spec.missingPercent ? leftOutFrames(*spec.missingPercent, n, seed) : std::vector<int>{};
  std::vector<FrameImperfection> frames(n);
  int kept = 0;
  for (int i = 0; i < n; ++i) {
    FrameImperfection& f = frames[i];
    f.index = i;
    f.showsUnseen = !showsUnseen.empty() && showsUnseen[i];
    f.leftOut = std::binary_search(leftOut.begin(), leftOut.end(), i) || f.showsUnseen;
    kept += !f.leftOut;
    f.truePose = f.writtenPose = walk[i];
    if (spec.pose) {
      Pcg32 rng = frameStream(seed, RandomStream::SynthPose, i);
      f.writtenPose = perturbPose(walk[i], *spec.pose, rng);
    }
    if (!spec.bracketStops.empty()) {
      f.exposure = static_cast<float>(std::exp2(spec.bracketStops[i % spec.bracketStops.size()]));
      f.exposureRecorded = true;
    }
    if (spec.whiteBalance) {
      Pcg32 rng = frameStream(seed, RandomStream::SynthWhiteBalance, i);
      for (int c = 0; c < 3; ++c) f.whiteBalance[c] = static_cast<float>(std::exp(*spec.whiteBalance * gaussian(rng)));
    }
    if (spec.exposureDrift) {
      Pcg32 rng = frameStream(seed, RandomStream::SynthExposureDrift, i);
      f.exposureDrift = static_cast<float>(std::exp(*spec.exposureDrift * gaussian(rng)));
    }
  }
  if (n > 0 && kept == 0)
    fail("imperfection 'unseen={}': every one of the {} training frames that 'missing' keeps shows it",
         spec.unseenObject, n);
  return frames;
}

void applySensor(const ImperfectionSpec& spec, const FrameImperfection& frame, uint64_t seed, Image& image) {
  Color gain = frame.whiteBalance * (frame.exposure * frame.exposureDrift);
  Pcg32 rng = frameStream(seed, RandomStream::SynthSensorNoise, frame.index);
  const float ceiling = spec.ldrBits ? 1.0f : std::numeric_limits<float>::infinity();
  for (size_t i = 0; i < image.rgb.size(); ++i) {
    float v = image.rgb[i] * gain[i % 3];
    if (spec.noise) {
      const double photons = spec.noise->photons;
      v = static_cast<float>(poisson(rng, photons * v) / photons + spec.noise->readSigma * gaussian(rng));
    }
    // Negative pixels mean "masked" to relume's readers; a sensor clips at zero and at full well.
    image.rgb[i] = std::clamp(v, 0.0f, ceiling);
  }
}

double displaceVertices(MeshData& mesh, const Length& noise, uint64_t seed) {
  const double radius = noise.metres();
  double largest = 0;
  for (Vec3& p : mesh.positions) {
    const Eigen::Vector3i q = (p / kVertexGrid).array().round().cast<int>();
    Pcg32 rng(hashTuple({seed, streamTag(RandomStream::SynthMeshNoise), static_cast<uint64_t>(q.x()),
                         static_cast<uint64_t>(q.y()), static_cast<uint64_t>(q.z())}));
    Vec3d u;
    do u = 2.0 * rng.next3D().cast<double>() - Vec3d::Ones();
    while (u.squaredNorm() > 1.0);
    const Vec3 moved = (p.cast<double>() + radius * u).cast<float>();
    largest = std::max(largest, static_cast<double>((moved - p).norm()));
    p = moved;
  }
  return largest;
}

Frame writeFlawedFrame(const ImperfectionSpec& spec, const FrameImperfection& frame, uint64_t seed,
                       const std::filesystem::path& exrPath, Image radiance) {
  applySensor(spec, frame, seed, radiance);
  Frame f;
  f.camera = frame.writtenPose;
  f.exposure = frame.exposure;
  f.exposureRecorded = frame.exposureRecorded;
  const std::filesystem::path pngPath = std::filesystem::path(exrPath).replace_extension(".png");
  f.image = spec.ldrBits ? pngPath : exrPath;
  std::filesystem::remove(spec.ldrBits ? exrPath : pngPath);  // an earlier capture's frame in the other format
  if (spec.ldrBits)
    writeSrgbPng(f.image, radiance, *spec.ldrBits);
  else
    writeExr(f.image, radiance);
  return f;
}

double writeFlawedMesh(const ImperfectionSpec& spec, MeshData mesh, const std::vector<std::string>& objectNames,
                       const std::filesystem::path& folder, uint64_t seed) {
  double largestOffset = 0;
  if (spec.meshNoise || !spec.absentObject.empty()) writePly(folder / "gt" / "mesh_clean.ply", mesh);
  if (spec.meshNoise) largestOffset = displaceVertices(mesh, *spec.meshNoise, seed);
  if (!spec.absentObject.empty()) {
    const int32_t absent = namedObject("absent", spec.absentObject, objectNames);
    size_t kept = 0;
    for (size_t f = 0; f < mesh.triangles.size(); ++f)
      if (mesh.faceObject[f] != absent)
        mesh.triangles[kept] = mesh.triangles[f], mesh.faceObject[kept] = mesh.faceObject[f], ++kept;
    mesh.triangles.resize(kept), mesh.faceObject.resize(kept);
  }
  if (!spec.segmentation) mesh.faceObject.clear(), mesh.objectNames.clear();
  writePly(folder / "mesh.ply", mesh);
  return largestOffset;
}

Json cameraToWorldJson(const Camera& c) {
  const Mat3 gl = c.rotationToOpenGL();
  Json m = Json::array();
  for (int r = 0; r < 3; ++r) m.push_back({gl(r, 0), gl(r, 1), gl(r, 2), c.position[r]});
  m.push_back({0, 0, 0, 1});
  return m;
}

Json imperfectionsJson(const ImperfectionSpec& s, uint64_t seed, const std::vector<FrameImperfection>& frames,
                       double largestVertexOffset) {
  Json parsed = Json::object();
  if (s.pose)
    parsed["pose"] = {{"translation_m", s.pose->translation.metres()},
                      {"rotation_deg", s.pose->rotation.radians() * 180 / kPi}};
  if (!s.bracketStops.empty()) parsed["bracket_stops"] = s.bracketStops;
  if (s.whiteBalance) parsed["wb_log_sigma"] = *s.whiteBalance;
  if (s.exposureDrift) parsed["exposure_drift_log_sigma"] = *s.exposureDrift;
  if (s.noise) parsed["noise"] = {{"photons_at_1", s.noise->photons}, {"read_sigma", s.noise->readSigma}};
  if (s.ldrBits) parsed["ldr_bits"] = *s.ldrBits;
  if (s.meshNoise)
    parsed["mesh"] = {{"max_offset_m", s.meshNoise->metres()},
                      {"largest_offset_m", largestVertexOffset},
                      {"true_mesh", "gt/mesh_clean.ply"}};
  parsed["segmentation"] = s.segmentation;
  if (!s.absentObject.empty()) parsed["absent_object"] = s.absentObject;
  if (!s.unseenObject.empty()) parsed["unseen_object"] = s.unseenObject;
  if (s.missingPercent) parsed["missing_percent"] = *s.missingPercent;
  Json list = Json::array(), leftOut = Json::array();
  for (const FrameImperfection& f : frames) {
    const double moved = (f.writtenPose.position - f.truePose.position).cast<double>().norm();
    const Eigen::AngleAxisd turn(f.writtenPose.rotation.cast<double>() *
                                 f.truePose.rotation.cast<double>().transpose());
    list.push_back({{"index", f.index},
                    {"left_out", f.leftOut},
                    {"shows_unseen", f.showsUnseen},
                    {"true_transform_matrix", cameraToWorldJson(f.truePose)},
                    {"written_transform_matrix", cameraToWorldJson(f.writtenPose)},
                    {"position_error_m", moved},
                    {"rotation_error_deg", turn.angle() * 180 / kPi},
                    {"exposure", f.exposure},
                    {"exposure_recorded", f.exposureRecorded},
                    {"wb_gain", {f.whiteBalance[0], f.whiteBalance[1], f.whiteBalance[2]}},
                    {"exposure_drift_gain", f.exposureDrift}});
    if (f.leftOut) leftOut.push_back(f.index);
  }
  return Json{{"spec", toString(s)}, {"seed", seed}, {"parsed", parsed}, {"left_out", leftOut}, {"frames", list}};
}

}  // namespace relume
