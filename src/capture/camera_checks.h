// Plausibility checks on a camera read from a capture, shared by every camera reader
// (transforms.json, COLMAP): the same bounds and the same messages whichever file a camera came from.
#pragma once
#include <string>

#include "core/camera.h"

namespace relume {

// Bounds of a plausible camera: beyond them Embree's rays are invalid or the input is garbage.
inline constexpr double kMaxFocal = 1e7;             // pixels
inline constexpr double kMaxPrincipalOffset = 10.0;  // |c - size/2| <= this many image sizes
inline constexpr double kMaxPosition = 1e6;          // metres, per coordinate
inline constexpr double kMaxImageSide = 65536;       // pixels
inline constexpr double kRotationTolerance = 1e-3;   // on R^T R - I and det R - 1, or on |q| - 1

// Intrinsics as a capture file gives them, in doubles, before any check.
struct RawIntrinsics {
  double width = 0, height = 0, fx = 0, fy = 0, cx = 0, cy = 0;
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0;
};

// What the file calls each field, so that an error names the field as the user wrote it.
struct IntrinsicNames {
  const char *width = "w", *height = "h", *fx = "fl_x", *fy = "fl_y", *cx = "cx", *cy = "cy";
};

// True if `v` is finite once stored as a float (the precision cameras use: 1e39 is not).
bool finiteInFloat(double v);

// Checks the size (integers in [1, 65536]), the focal lengths (in (0, kMaxFocal)) and the principal
// point (within kMaxPrincipalOffset image sizes of the centre) and returns the camera with an
// identity pose. Errors are one line: "<where>: '<field>' is ..., must be ...".
Camera checkedIntrinsics(const RawIntrinsics& in, const IntrinsicNames& names, const std::string& where);

// One coordinate of a camera position, within +-kMaxPosition: "<where>: <field> is ..., must be within ...".
void checkPositionCoordinate(double value, const std::string& where, const std::string& field);

}  // namespace relume
