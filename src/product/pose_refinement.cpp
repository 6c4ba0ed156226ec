#include "product/pose_refinement.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include <Eigen/Dense>

#include "capture/frame_store.h"
#include "core/check.h"
#include "render/film.h"
#include "scene/scene.h"

namespace relume {
namespace {

using Mat3d = Eigen::Matrix3d;
using Vec7d = Eigen::Matrix<double, 7, 1>;
using Mat7d = Eigen::Matrix<double, 7, 7>;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kHuber = 1.345;  // x the residuals' robust spread: 95% efficiency on Gaussian noise
// Pixels that share one noise after the binomial blur (sigma 1): 4 pi sigma^2.
constexpr double kBlurShare = 4 * M_PI;

// A pose in double: camera-to-world rotation and position (OpenCV axes, as Camera).
struct Pose {
  Mat3d rotation;
  Vec3d position;
};
Pose poseOf(const Camera& c) { return {c.rotation.cast<double>(), c.position.cast<double>()}; }

// The update of a 6-vector (omega, v) in the camera's frame: R' = R exp([omega]), t' = t + R v, so
// a camera-frame point X_c becomes exp(-[omega]) (X_c - v).
Pose updated(const Pose& p, const Eigen::Matrix<double, 6, 1>& d) {
  const Vec3d omega = d.head<3>();
  const double angle = omega.norm();
  const Mat3d turn = angle > 0 ? Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix() : Mat3d::Identity();
  return {p.rotation * turn, p.position + p.rotation * d.tail<3>()};
}

// One pyramid level: the model's log luminance and first-hit point per pixel, the frame's log
// luminance (NaN: not usable), and the camera at this size.
struct Level {
  Camera camera;
  int width = 0, height = 0;
  std::vector<float> logFrame;
  struct Point {
    Vec3d world;
    double logModel;
  };
  std::vector<Point> points;
};

// Bilinear lookup at continuous pixel coordinates (centres at +0.5); NaN outside or next to a NaN.
double bilinear(const std::vector<float>& img, int w, int h, double x, double y) {
  const double u = x - 0.5, v = y - 0.5;
  const int i = static_cast<int>(std::floor(u)), j = static_cast<int>(std::floor(v));
  if (i < 0 || j < 0 || i + 1 >= w || j + 1 >= h) return kNaN;
  const double fu = u - i, fv = v - j;
  const size_t k = static_cast<size_t>(j) * w + i;
  return (1 - fv) * ((1 - fu) * img[k] + fu * img[k + 1]) + fv * ((1 - fu) * img[k + w] + fu * img[k + w + 1]);
}

// The 2x2 box mean of an image of w x h (NaN where any of the four is).
std::vector<float> halve(const std::vector<float>& img, int w, int h) {
  const int W = w / 2, H = h / 2;
  std::vector<float> out(static_cast<size_t>(W) * H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const size_t k = static_cast<size_t>(2 * y) * w + 2 * x;
      out[static_cast<size_t>(y) * W + x] = 0.25f * (img[k] + img[k + 1] + img[k + w] + img[k + w + 1]);
    }
  return out;
}

// The binomial blur [1 4 6 4 1] / 16 in x then y (sigma 1 pixel); NaN where the kernel meets one,
// and within two pixels of the border. It widens the basin a level's steps converge in.
std::vector<float> blurred(const std::vector<float>& img, int w, int h) {
  constexpr float k[5] = {1 / 16.f, 4 / 16.f, 6 / 16.f, 4 / 16.f, 1 / 16.f};
  std::vector<float> tmp(img.size(), kNaN), out(img.size(), kNaN);
  for (int y = 0; y < h; ++y)
    for (int x = 2; x + 2 < w; ++x) {
      float sum = 0;
      for (int i = -2; i <= 2; ++i) sum += k[i + 2] * img[static_cast<size_t>(y) * w + x + i];
      tmp[static_cast<size_t>(y) * w + x] = sum;
    }
  for (int y = 2; y + 2 < h; ++y)
    for (int x = 0; x < w; ++x) {
      float sum = 0;
      for (int j = -2; j <= 2; ++j) sum += k[j + 2] * tmp[static_cast<size_t>(y + j) * w + x];
      out[static_cast<size_t>(y) * w + x] = sum;
    }
  return out;
}

Camera scaled(const Camera& c, double factor, int width, int height) {
  Camera s = c;
  s.fx = static_cast<float>(c.fx * factor), s.fy = static_cast<float>(c.fy * factor);
  s.cx = static_cast<float>(c.cx * factor), s.cy = static_cast<float>(c.cy * factor);
  s.width = width, s.height = height;
  return s;
}

// The residuals' cost and normal equations at one pose and brightness offset: residual
// r = log(eps + frame(project(X))) - log(eps + model) - beta, Huber-weighted at `k`.
struct Normal {
  Mat7d H = Mat7d::Zero();
  Vec7d g = Vec7d::Zero();
  double cost = 0;
  int used = 0;
  double meanCost() const { return used > 0 ? cost / used : INFINITY; }
};

double huber(double r, double k) { return std::abs(r) <= k ? 0.5 * r * r : k * (std::abs(r) - 0.5 * k); }

// Projects camera-frame point xc with level camera `cam` (its distortion included).
std::optional<Eigen::Vector2d> projectLocal(const Camera& cam, const Vec3d& xc) {
  if (xc.z() <= 1e-6) return std::nullopt;
  const Vec2 d = cam.distort(Vec2(static_cast<float>(xc.x() / xc.z()), static_cast<float>(xc.y() / xc.z())));
  return Eigen::Vector2d(cam.fx * d.x() + cam.cx, cam.fy * d.y() + cam.cy);
}

Normal normalEquations(const Level& L, const Pose& pose, double beta, double k, bool withJacobian) {
  Normal n;
  const Mat3d Rt = pose.rotation.transpose();
  for (const Level::Point& p : L.points) {
    const Vec3d xc = Rt * (p.world - pose.position);
    const auto q = projectLocal(L.camera, xc);
    if (!q) continue;
    const double observed = bilinear(L.logFrame, L.width, L.height, q->x(), q->y());
    if (!std::isfinite(observed)) continue;
    const double r = observed - p.logModel - beta;
    const double w = std::abs(r) <= k ? 1.0 : k / std::abs(r);
    n.cost += huber(r, k);
    ++n.used;
    if (!withJacobian) continue;
    // Image gradient by central differences of the bilinear interpolant, one pixel either side.
    const double gx = 0.5 * (bilinear(L.logFrame, L.width, L.height, q->x() + 1, q->y()) -
                             bilinear(L.logFrame, L.width, L.height, q->x() - 1, q->y()));
    const double gy = 0.5 * (bilinear(L.logFrame, L.width, L.height, q->x(), q->y() + 1) -
                             bilinear(L.logFrame, L.width, L.height, q->x(), q->y() - 1));
    if (!std::isfinite(gx) || !std::isfinite(gy)) continue;
    // dq/dX_c of the pinhole (distortion's own derivative left out: it changes the step, not the
    // residual it is judged by), and dX_c/d(omega, v) = ([X_c]x, -I).
    const double iz = 1.0 / xc.z();
    Eigen::Matrix<double, 2, 3> dq;
    dq << L.camera.fx * iz, 0, -L.camera.fx * xc.x() * iz * iz, 0, L.camera.fy * iz, -L.camera.fy * xc.y() * iz * iz;
    const Eigen::RowVector3d dX = Eigen::RowVector2d(gx, gy) * dq;
    Mat3d cross;
    cross << 0, -xc.z(), xc.y(), xc.z(), 0, -xc.x(), -xc.y(), xc.x(), 0;
    Vec7d J;
    J.head<3>() = (dX * cross).transpose();
    J.segment<3>(3) = -dX.transpose();
    J[6] = -1;
    n.H += w * J * J.transpose();
    n.g += w * r * J;
  }
  return n;
}

// The brightness offset that best lines the frame up with the model at `pose` (the residuals'
// median: robust, no scale needed) and the residuals' robust spread (1.4826 MAD).
std::pair<double, double> offsetAndSpread(const Level& L, const Pose& pose) {
  std::vector<double> r;
  const Mat3d Rt = pose.rotation.transpose();
  for (const Level::Point& p : L.points) {
    const auto q = projectLocal(L.camera, Rt * (p.world - pose.position));
    if (!q) continue;
    const double observed = bilinear(L.logFrame, L.width, L.height, q->x(), q->y());
    if (std::isfinite(observed)) r.push_back(observed - p.logModel);
  }
  if (r.empty()) return {0.0, 0.0};
  const double m = medianOf(r);
  for (double& x : r) x = std::abs(x - m);
  return {m, 1.4826 * medianOf(r)};
}

}  // namespace

const char* alignStatusName(AlignStatus s) {
  switch (s) {
    case AlignStatus::Aligned: return "aligned";
    case AlignStatus::Unchanged: return "unchanged";
    case AlignStatus::Failed: return "failed";
  }
  return "?";
}

double poseTranslation(const Camera& from, const Camera& to) {
  return (to.position.cast<double>() - from.position.cast<double>()).norm();
}

double poseRotationDeg(const Camera& from, const Camera& to) {
  const Eigen::AngleAxisd turn(to.rotation.cast<double>() * from.rotation.cast<double>().transpose());
  return turn.angle() * 180.0 / M_PI;
}

AlignImage alignImageFromStore(const FrameStore& store, size_t frame, float gain, int maxWidth, Camera& camera) {
  CHECK(maxWidth > 0);
  const FrameStats& st = store.stats(frame);
  const int sw = static_cast<int>(st.width), sh = static_cast<int>(st.height);
  const int block = std::max(1, (sw + maxWidth - 1) / maxWidth);
  AlignImage img;
  img.width = sw / block, img.height = sh / block;
  img.luminance.assign(static_cast<size_t>(img.width) * img.height, kNaN);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      double sum = 0;
      bool usable = true;
      for (int j = 0; j < block && usable; ++j)
        for (int i = 0; i < block && usable; ++i) {
          const Color c = store.pixel(frame, x * block + i, y * block + j);
          usable = c.minCoeff() >= 0 && (c < st.clipHigh).all() && (c > st.clipLow).any();
          sum += luminance(c);
        }
      if (usable) img.luminance[static_cast<size_t>(y) * img.width + x] = static_cast<float>(sum / (block * block) / gain);
    }
  const double factor = 1.0 / (static_cast<double>(st.downscale) * block);
  const PixelFilter filter = block * st.downscale == 1 ? camera.filter : PixelFilter{};
  camera = scaled(camera, factor, img.width, img.height);
  camera.filter = filter;
  return img;
}

Camera targetGrid(const Camera& camera) {
  Camera grid = camera;
  grid.cx -= 0.5f, grid.cy -= 0.5f;
  return grid;
}

AlignImage renderedTarget(const Scene& scene, const Appearance& model, const LightSampler& lights, const Camera& grid,
                          int spp, uint64_t seed, const PathSettings& path) {
  RenderOptions ro;
  ro.spp = spp, ro.seed = seed, ro.path = path;
  const Image render = renderImage(scene, model, lights, grid, ro).color;
  AlignImage out;
  out.width = render.width, out.height = render.height;
  out.luminance.resize(static_cast<size_t>(out.width) * out.height);
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) out.luminance[static_cast<size_t>(y) * out.width + x] = luminance(render.at(x, y));
  return out;
}

FrameAlignment alignFrame(const Scene& scene, const Camera& camera, const AlignImage& frame, const AlignImage& target,
                          const PoseAlignSettings& s) {
  CHECK_EQ(camera.width, frame.width);
  CHECK_EQ(camera.height, frame.height);
  CHECK_EQ(target.width, frame.width);
  CHECK_EQ(target.height, frame.height);
  FrameAlignment out;
  out.camera = camera;
  const Camera shifted = targetGrid(camera);
  std::vector<float> sorted;
  for (float v : target.luminance)
    if (v > 0) sorted.push_back(v);
  if (sorted.size() < static_cast<size_t>(s.minPixels)) {
    out.status = AlignStatus::Failed, out.why = fmt::format("the target shows {} lit pixels", sorted.size());
    return out;
  }
  // Dark pixels' logs are noise: eps is a fiftieth of the target's median luminance.
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const float eps = std::max(1e-6f, 0.02f * sorted[sorted.size() / 2]);

  // The pyramid, finest first.
  std::vector<Level> levels;
  std::vector<float> frameLum = frame.luminance, rendered = target.luminance;
  int w = frame.width, h = frame.height;
  for (int l = 0; l < s.levels && w >= 16 && h >= 16; ++l) {
    Level L;
    L.camera = l == 0 ? camera : scaled(camera, std::ldexp(1.0, -l), w, h);
    const Camera modelCamera = l == 0 ? shifted : scaled(shifted, std::ldexp(1.0, -l), w, h);
    L.width = w, L.height = h;
    L.logFrame = blurred(frameLum, w, h);
    for (float& v : L.logFrame) v = std::log(eps + v);  // NaN stays NaN
    const std::vector<float> modelBlurred = blurred(rendered, w, h);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float m = modelBlurred[static_cast<size_t>(y) * w + x];
        const auto dir = modelCamera.rayDirection(Vec2(x + 0.5f, y + 0.5f));
        if (!(m >= 0) || !dir) continue;
        const auto hit = scene.intersect(L.camera.position, *dir);
        if (hit) L.points.push_back({hit->p.cast<double>(), std::log(eps + m)});
      }
    levels.push_back(std::move(L));
    frameLum = halve(frameLum, w, h), rendered = halve(rendered, w, h);
    w /= 2, h /= 2;
  }

  const Pose start = poseOf(camera);
  Pose pose = start;
  const Level& finest = levels.front();
  const auto [beta0, spread0] = offsetAndSpread(finest, start);
  const double k0 = kHuber * std::max(spread0, 1e-3);
  out.costBefore = normalEquations(finest, start, beta0, k0, false).meanCost();
  // The correction is a MAP estimate: the data in units of the residuals' own spread, counted as
  // the independent pixels the blur leaves (4 pi sigma^2 pixels share one noise), plus a Gaussian
  // prior on the correction of the given pose's accuracy. Along a direction the frame barely fixes
  // (a turn and a sideways move that look alike), the noise would otherwise walk the pose far off.
  Eigen::Matrix<double, 6, 1> prior;
  const double r = s.priorRotationDeg * M_PI / 180;
  prior << 1 / (r * r), 1 / (r * r), 1 / (r * r), 1 / (s.priorTranslation * s.priorTranslation),
      1 / (s.priorTranslation * s.priorTranslation), 1 / (s.priorTranslation * s.priorTranslation);
  auto correction = [&](const Pose& p) {
    Eigen::Matrix<double, 6, 1> c;
    const Eigen::AngleAxisd turn(start.rotation.transpose() * p.rotation);
    c.head<3>() = turn.angle() * turn.axis();
    c.tail<3>() = start.rotation.transpose() * (p.position - start.position);
    return c;
  };
  struct Total {
    Normal n;
    double cost;
  };
  auto total = [&](const Level& L, const Pose& p, double b, double k, double spread) {
    Total t{normalEquations(L, p, b, k, true), 0};
    const double w = 1.0 / (kBlurShare * spread * spread);
    const Eigen::Matrix<double, 6, 1> c = correction(p);
    t.n.H *= w, t.n.g *= w;
    t.n.H.topLeftCorner<6, 6>() += Eigen::Matrix<double, 6, 6>(prior.asDiagonal());
    t.n.g.head<6>() += prior.cwiseProduct(c);
    t.cost = w * t.n.cost + 0.5 * c.dot(prior.cwiseProduct(c));
    return t;
  };
  double beta = beta0;
  for (size_t l = levels.size(); l-- > 0;) {
    const Level& L = levels[l];
    const auto [b, spreadL] = offsetAndSpread(L, pose);
    beta = b;
    const double spread = std::max(spreadL, 1e-3), k = kHuber * spread;
    double lambda = 1e-3;
    Total t = total(L, pose, beta, k, spread);
    for (int it = 0; it < s.iterations && t.n.used > 0; ++it) {
      const Mat7d A = t.n.H + lambda * Mat7d(t.n.H.diagonal().asDiagonal());
      const Vec7d d = A.ldlt().solve(-t.n.g);
      if (!d.allFinite()) break;
      const Pose trial = updated(pose, d.head<6>());
      const Total tt = total(L, trial, beta + d[6], k, spread);
      if (tt.n.used > 0 && tt.cost < t.cost) {
        pose = trial, beta += d[6], t = tt;
        lambda = std::max(lambda * 0.1, 1e-6);
        if (d.head<3>().norm() < 1e-7 && d.segment<3>(3).norm() < 1e-7) break;
      } else {
        lambda *= 10;
        if (lambda > 1e6) break;
      }
    }
  }

  // How well the finest level fixes the 6 degrees of freedom: translations in units of the
  // median depth, so that both blocks are radians of image motion.
  std::vector<double> depth;
  for (const Level::Point& p : finest.points) depth.push_back((p.world - start.position).norm());
  std::nth_element(depth.begin(), depth.begin() + depth.size() / 2, depth.end());
  const double z = depth.empty() ? 1.0 : depth[depth.size() / 2];
  Normal fn = normalEquations(finest, pose, beta, k0, true);
  out.pixels = fn.used;
  Eigen::Matrix<double, 6, 6> P = fn.H.topLeftCorner<6, 6>();
  const Eigen::Matrix<double, 6, 1> scale = (Eigen::Matrix<double, 6, 1>() << 1, 1, 1, z, z, z).finished();
  P = scale.asDiagonal() * P * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(P);
  out.conditioning = eig.eigenvalues().maxCoeff() > 0 ? eig.eigenvalues().minCoeff() / eig.eigenvalues().maxCoeff() : 0;

  Camera refined = camera;
  refined.rotation = pose.rotation.cast<float>();
  refined.position = pose.position.cast<float>();
  const double moved = poseTranslation(camera, refined), turned = poseRotationDeg(camera, refined);
  out.costAfter = normalEquations(finest, pose, offsetAndSpread(finest, pose).first, k0, false).meanCost();
  if (out.pixels < s.minPixels) {
    out.status = AlignStatus::Failed, out.why = fmt::format("{} usable pixels (at least {})", out.pixels, s.minPixels);
  } else if (!(out.conditioning >= s.minConditioning)) {
    out.status = AlignStatus::Failed;
    out.why = fmt::format("the frame fixes too few of the pose's 6 degrees of freedom (conditioning {:.2g})",
                          out.conditioning);
  } else if (!(moved <= s.maxTranslation && turned <= s.maxRotationDeg)) {
    out.status = AlignStatus::Failed;
    out.why = fmt::format("the correction ({:.1f} cm, {:.2f} deg) is beyond the limits ({:.1f} cm, {:.2f} deg)",
                          100 * moved, turned, 100 * s.maxTranslation, s.maxRotationDeg);
  } else if (!(out.costAfter < out.costBefore)) {
    out.status = AlignStatus::Unchanged, out.why = "no pose near it explains the frame better";
  } else {
    out.status = AlignStatus::Aligned;
    out.camera = refined;
  }
  return out;
}

}  // namespace relume
