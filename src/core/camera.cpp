#include "core/camera.h"

namespace relume {

Vec2 Camera::distort(const Vec2& p) const {
  const Distortion& d = distortion;
  const float x = p.x(), y = p.y();
  const float r2 = x * x + y * y;
  const float radial = 1.0f + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
  return {x * radial + 2.0f * d.p1 * x * y + d.p2 * (r2 + 2.0f * x * x),
          y * radial + d.p1 * (r2 + 2.0f * y * y) + 2.0f * d.p2 * x * y};
}

std::optional<Vec2> Camera::undistort(const Vec2& target) const {
  if (!distortion.active()) return target;
  Vec2 p = target;
  const float h = 1e-4f;
  for (int it = 0; it < 20; ++it) {
    const Vec2 residual = distort(p) - target;
    if (residual.squaredNorm() < 1e-14f) return p;
    // Jacobian by central differences: cheap and exact enough for a 2x2 Newton step.
    Eigen::Matrix2f J;
    J.col(0) = (distort(p + Vec2(h, 0)) - distort(p - Vec2(h, 0))) / (2 * h);
    J.col(1) = (distort(p + Vec2(0, h)) - distort(p - Vec2(0, h))) / (2 * h);
    const float det = J.determinant();
    if (!(std::abs(det) > 1e-8f)) return std::nullopt;
    p -= J.inverse() * residual;
    if (!p.allFinite()) return std::nullopt;
  }
  return (distort(p) - target).squaredNorm() < 1e-10f ? std::optional<Vec2>(p) : std::nullopt;
}

std::optional<Vec2> Camera::project(const Vec3& world) const {
  const Vec3 local = rotation.transpose() * (world - position);
  if (local.z() <= 1e-6f) return std::nullopt;
  const Vec2 d = distort(Vec2(local.x() / local.z(), local.y() / local.z()));
  return Vec2(fx * d.x() + cx, fy * d.y() + cy);
}

std::optional<Vec3> Camera::rayDirection(const Vec2& pixel) const {
  const auto p = undistort(Vec2((pixel.x() - cx) / fx, (pixel.y() - cy) / fy));
  if (!p) return std::nullopt;
  return (rotation * Vec3(p->x(), p->y(), 1.0f)).normalized();
}

Mat3 Camera::rotationFromOpenGL(const Mat3& gl) {
  Mat3 r = gl;
  r.col(1) = -gl.col(1);
  r.col(2) = -gl.col(2);
  return r;
}

Mat3 Camera::rotationToOpenGL() const { return rotationFromOpenGL(rotation); }

}  // namespace relume
