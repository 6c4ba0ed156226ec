#include "capture/camera_checks.h"

#include <cmath>

#include "core/error.h"

namespace relume {

bool finiteInFloat(double v) { return std::isfinite(static_cast<float>(v)); }

Camera checkedIntrinsics(const RawIntrinsics& in, const IntrinsicNames& names, const std::string& where) {
  const double w = in.width, h = in.height;
  if (!(w >= 1 && w <= kMaxImageSide && h >= 1 && h <= kMaxImageSide) || w != std::floor(w) || h != std::floor(h))
    fail("{}: bad image size {}x{} (integers in [1, {:g}])", where, w, h, kMaxImageSide);
  if (!(in.fx > 0 && in.fx < kMaxFocal))
    fail("{}: '{}' is {}, must be in (0, {:g}) pixels", where, names.fx, in.fx, kMaxFocal);
  if (!(in.fy > 0 && in.fy < kMaxFocal))
    fail("{}: '{}' is {}, must be in (0, {:g}) pixels", where, names.fy, in.fy, kMaxFocal);
  if (!(std::abs(in.cx - 0.5 * w) <= kMaxPrincipalOffset * w))
    fail("{}: '{}' is {}, must be in [{}, {}] (image width {} times {} around its centre)", where, names.cx, in.cx,
         0.5 * w - kMaxPrincipalOffset * w, 0.5 * w + kMaxPrincipalOffset * w, w, kMaxPrincipalOffset);
  if (!(std::abs(in.cy - 0.5 * h) <= kMaxPrincipalOffset * h))
    fail("{}: '{}' is {}, must be in [{}, {}] (image height {} times {} around its centre)", where, names.cy, in.cy,
         0.5 * h - kMaxPrincipalOffset * h, 0.5 * h + kMaxPrincipalOffset * h, h, kMaxPrincipalOffset);
  for (const double k : {in.k1, in.k2, in.p1, in.p2, in.k3})
    if (!finiteInFloat(k)) fail("{}: distortion coefficient {} is not finite in float", where, k);
  Camera c;
  c.width = static_cast<int>(w);
  c.height = static_cast<int>(h);
  c.fx = static_cast<float>(in.fx);
  c.fy = static_cast<float>(in.fy);
  c.cx = static_cast<float>(in.cx);
  c.cy = static_cast<float>(in.cy);
  c.distortion = {static_cast<float>(in.k1), static_cast<float>(in.k2), static_cast<float>(in.p1),
                  static_cast<float>(in.p2), static_cast<float>(in.k3)};
  return c;
}

void checkPositionCoordinate(double value, const std::string& where, const std::string& field) {
  if (!(std::abs(value) < kMaxPosition))
    fail("{}: {} is {}, must be within +-{:g} m", where, field, value, kMaxPosition);
}

}  // namespace relume
