// Ray queries against the mesh (Embree 3 BVH) and surface attributes at a hit.
#pragma once
#include <embree3/rtcore.h>

#include <atomic>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/prefetch.h"
#include "scene/mesh.h"

namespace relume {

struct SurfaceHit {
  Vec3 p = Vec3::Zero();
  Vec3 ng = Vec3::UnitZ();  // unit geometric normal in winding order (emitters emit on this side)
  Vec3 ns = Vec3::UnitZ();  // unit shading normal, same side as ng
  Vec2 uv = Vec2::Zero();   // atlas uv (zero when the mesh has none)
  uint32_t prim = 0;
  int object = 0;
  float t = 0;
};

// A closest hit before its surface attributes are gathered: a wavefront of paths keeps it between
// traversal and shading, so the face record that `traverse` prefetches has landed when it is read.
struct RayHit {
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  uint32_t prim = kNone;
  float b1 = 0, b2 = 0, t = 0;  // barycentrics of vertices 1 and 2, ray distance
  bool found() const { return prim != kNone; }
};

struct SceneOptions {
  bool robust = false;  // RTC_SCENE_FLAG_ROBUST: its measured cost: docs/design/rendering.md
};

class Scene {
 public:
  explicit Scene(TriangleMesh mesh, SceneOptions options = {});
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  const TriangleMesh& mesh() const { return mesh_; }
  // Every ray entry point checks its ray first: a non-finite origin or direction, or a tmax that is
  // NaN or negative (an inverted segment), never reaches Embree. Debug builds assert; release builds
  // skip the ray (intersect: no hit, occluded: true, hitDistance: infinity) and count it.
  std::optional<SurfaceHit> intersect(const Vec3& origin, const Vec3& dir, float tmax = INFINITY) const;
  // intersect() in two steps: the traversal (which starts loading the hit's face record), and the
  // hit's surface attributes.
  RayHit traverse(const Vec3& origin, const Vec3& dir, float tmax = INFINITY) const;
  SurfaceHit surfaceAt(const RayHit& hit, const Vec3& origin, const Vec3& dir) const;
  bool occluded(const Vec3& origin, const Vec3& dir, float tmax) const;
  // Closest-hit distance only (no surface attributes): Embree's cost alone, for profiling.
  float hitDistance(const Vec3& origin, const Vec3& dir, float tmax = INFINITY) const;
  // The surface attributes of face `prim` at barycentrics (1 - b1 - b2, b1, b2) from its face record
  // alone: everything but the position p and the distance t.
  SurfaceHit hitFromFace(uint32_t prim, float b1, float b2) const;
  // Starts loading the face record hitFromFace reads (76 bytes: two or three cache lines).
  [[gnu::always_inline]] void prefetchFace(uint32_t prim) const { prefetchObject(&faces_[prim]); }
  // Origin nudged off the surface towards `dir`, scaled to the coordinate magnitude.
  static Vec3 offsetOrigin(const SurfaceHit& hit, const Vec3& dir);
  size_t skippedRays() const { return skippedRays_.load(std::memory_order_relaxed); }
  // An error Embree reported (out of memory, an invalid argument) fails the command: the first
  // one is kept, and this throws relume::Error with it. The constructor calls it; so do the
  // loops that trace many rays, once per pass.
  void throwIfEmbreeFailed() const;
  RTCDevice embreeDevice() const { return device_; }
  // Bytes the scene holds: Embree's (its BVH, as its device reports them), the face records and
  // the vertex buffer (the mesh's own arrays not counted).
  size_t bytes() const;

 private:
  TriangleMesh mesh_;
  // Everything shading needs of a face in one 76-byte record: after Embree's traversal the mesh
  // arrays are cold, and gathering them from several places (the triangle's indices, then its
  // uvs, vertex normals and positions) dominated hit processing.
  struct FaceRecord {
    Vec3 ng;
    int32_t object;
    Vec2 uv[3];
    Vec3 n[3];  // vertex normals (zero when the mesh has none)
  };
  bool traceable(const Vec3& origin, const Vec3& dir, float tmax) const;
  static void onEmbreeError(void* scene, RTCError code, const char* message);
  static bool onEmbreeMemory(void* scene, ssize_t bytes, bool post);
  void release();
  std::atomic<bool> embreeFailed_{false};  // set once the first error is stored
  mutable std::mutex embreeErrorMutex_;
  int embreeErrorCode_ = RTC_ERROR_NONE;
  std::string embreeMessage_;
  std::vector<float> vertexBuffer_;  // xyz + padding so Embree can read 16 bytes at the end
  std::vector<FaceRecord> faces_;
  RTCDevice device_ = nullptr;
  RTCScene scene_ = nullptr;
  mutable std::atomic<size_t> skippedRays_{0};
  std::atomic<int64_t> embreeBytes_{0};
};

// The point with barycentrics (1 - b1 - b2, b1, b2) of a triangle's corners.
inline Vec3 barycentricPoint(const Vec3& p0, const Vec3& p1, const Vec3& p2, float b1, float b2) {
  return (1.0f - b1 - b2) * p0 + b1 * p1 + b2 * p2;
}

inline float rayEpsilon(const Vec3& p) { return 1e-4f * (1.0f + p.cwiseAbs().maxCoeff()); }

}  // namespace relume
