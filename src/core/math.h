// Basic math types (Eigen fixed-size) and small helpers shared by every module.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace relume {

using Vec2 = Eigen::Vector2f;
using Vec3 = Eigen::Vector3f;
using Vec3d = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3f;
using Mat4d = Eigen::Matrix4d;
using Color = Eigen::Array3f;  // linear Rec.709 RGB

inline constexpr float kPi = 3.14159265358979323846f;
inline constexpr float kInvPi = 1.0f / kPi;

inline float luminance(const Color& c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }
inline bool isFinite(const Color& c) { return std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]); }
inline float safeSqrt(float x) { return std::sqrt(std::max(x, 0.0f)); }
template <typename T>
inline T sqr(T x) {
  return x * x;
}

// The upper median (element size/2 in order); 0 for none.
template <typename T>
T medianOf(std::vector<T> v) {
  if (v.empty()) return T(0);
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// The point of triangle (a, b, c) nearest to p: the nearest of its face, edges and corners, by the
// region of the triangle's plane p projects into (Ericson, Real-Time Collision Detection, 5.1.5).
inline Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const float d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const float d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const float d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const float denominator = 1 / (va + vb + vc);
  return a + ab * (vb * denominator) + ac * (vc * denominator);
}

// Orthonormal basis around a unit normal (Duff et al. 2017, branchless).
struct ShadingFrame {
  Vec3 s, t, n;
  ShadingFrame() = default;
  explicit ShadingFrame(const Vec3& normal) : n(normal) {
    const float sign = std::copysign(1.0f, n.z());
    const float a = -1.0f / (sign + n.z());
    const float b = n.x() * n.y() * a;
    s = Vec3(1.0f + sign * n.x() * n.x() * a, sign * b, -sign * n.x());
    t = Vec3(b, sign + n.y() * n.y() * a, -n.y());
  }
  Vec3 toLocal(const Vec3& v) const { return {v.dot(s), v.dot(t), v.dot(n)}; }
  Vec3 toWorld(const Vec3& v) const { return s * v.x() + t * v.y() + n * v.z(); }
};

}  // namespace relume
