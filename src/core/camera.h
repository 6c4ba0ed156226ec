// Pinhole camera with optional OpenCV radial-tangential distortion.
// Internal convention is OpenCV: x right, y down, z forward; pixel centres at (i+0.5, j+0.5).
// Distortion is applied in the forward projection; ray generation inverts it (Newton), so no
// image is ever resampled.
#pragma once
#include <optional>

#include "core/math.h"
#include "core/pixel_filter.h"

namespace relume {

struct Distortion {
  float k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
  bool active() const { return k1 != 0 || k2 != 0 || p1 != 0 || p2 != 0 || k3 != 0; }
};

struct Camera {
  int width = 0, height = 0;
  float fx = 1, fy = 1, cx = 0, cy = 0;
  Distortion distortion;
  Mat3 rotation = Mat3::Identity();  // camera-to-world, OpenCV axes
  Vec3 position = Vec3::Zero();
  PixelFilter filter;  // what the camera's pixels average over (rays for a pixel are drawn from it)

  // Normalised undistorted image-plane point -> distorted normalised point.
  Vec2 distort(const Vec2& p) const;
  // Inverse of distort by Newton iteration; nullopt if it does not converge (outside the valid region).
  std::optional<Vec2> undistort(const Vec2& distorted) const;

  // World point -> pixel coordinates (continuous, top-left corner at 0). nullopt if behind the camera.
  std::optional<Vec2> project(const Vec3& world) const;
  // Pixel coordinates -> unit world-space direction from `position`.
  std::optional<Vec3> rayDirection(const Vec2& pixel) const;

  // transforms.json stores camera-to-world in OpenGL axes (y up, z back): flip y and z.
  static Mat3 rotationFromOpenGL(const Mat3& glCamToWorld);
  Mat3 rotationToOpenGL() const;
};

}  // namespace relume
