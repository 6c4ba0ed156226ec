#include "scene/scene.h"

#include <spdlog/spdlog.h>

#include "core/check.h"
#include "core/error.h"

namespace relume {
void Scene::onEmbreeError(void* scene, RTCError code, const char* message) {
  Scene& s = *static_cast<Scene*>(scene);
  spdlog::debug("embree error {}: {}", static_cast<int>(code), message ? message : "");
  const std::lock_guard<std::mutex> lock(s.embreeErrorMutex_);
  if (s.embreeFailed_.load()) return;
  s.embreeErrorCode_ = code;
  s.embreeMessage_ = message ? message : "";
  s.embreeFailed_.store(true);
}

void Scene::throwIfEmbreeFailed() const {
  if (!embreeFailed_.load(std::memory_order_relaxed)) return;
  const std::lock_guard<std::mutex> lock(embreeErrorMutex_);
  fail("embree error {} on a mesh of {} triangles: {}", embreeErrorCode_, mesh_.triangles.size(), embreeMessage_);
}

bool Scene::onEmbreeMemory(void* scene, ssize_t bytes, bool /*post*/) {
  static_cast<Scene*>(scene)->embreeBytes_.fetch_add(bytes, std::memory_order_relaxed);
  return true;  // never refuses an allocation: a memory budget is kept by sizing the fit beforehand
}

size_t Scene::bytes() const {
  return static_cast<size_t>(std::max<int64_t>(0, embreeBytes_.load(std::memory_order_relaxed))) +
         vertexBuffer_.size() * sizeof(float) + faces_.size() * sizeof(FaceRecord);
}

Scene::Scene(TriangleMesh mesh, SceneOptions options) : mesh_(std::move(mesh)) {
  device_ = rtcNewDevice(nullptr);
  if (!device_) fail("cannot create Embree device (error {})", static_cast<int>(rtcGetDeviceError(nullptr)));
  rtcSetDeviceErrorFunction(device_, onEmbreeError, this);
  rtcSetDeviceMemoryMonitorFunction(device_, onEmbreeMemory, this);
  scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(scene_, options.robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  vertexBuffer_.resize(mesh_.positions.size() * 3 + 1);
  for (size_t i = 0; i < mesh_.positions.size(); ++i)
    for (int k = 0; k < 3; ++k) vertexBuffer_[3 * i + k] = mesh_.positions[i][k];
  faces_.resize(mesh_.triangles.size());
  for (size_t f = 0; f < faces_.size(); ++f) {
    FaceRecord& r = faces_[f];
    r.ng = mesh_.faceNormal(f);
    r.object = mesh_.faceObject[f];
    for (int k = 0; k < 3; ++k) {
      const int v = mesh_.triangles[f][k];
      r.uv[k] = mesh_.hasUv() ? mesh_.uvs[v] : Vec2::Zero();
      r.n[k] = mesh_.normals.empty() ? Vec3::Zero() : mesh_.normals[v];
    }
  }
  rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertexBuffer_.data(), 0,
                             3 * sizeof(float), mesh_.positions.size());
  rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh_.triangles.data(), 0,
                             sizeof(Eigen::Vector3i), mesh_.triangles.size());
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene_, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene_);
  if (embreeFailed_.load()) {
    release();  // the destructor does not run when the constructor throws
    throwIfEmbreeFailed();
  }
}

void Scene::release() {
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
  scene_ = nullptr, device_ = nullptr;
}

Scene::~Scene() { release(); }

SurfaceHit Scene::hitFromFace(uint32_t prim, float b1, float b2) const {
  const FaceRecord& face = faces_[prim];
  const float b0 = 1.0f - b1 - b2;
  SurfaceHit h;
  h.prim = prim;
  h.object = face.object;
  h.ng = face.ng;
  h.ns = face.ng;
  h.uv = b0 * face.uv[0] + b1 * face.uv[1] + b2 * face.uv[2];
  // A degenerate interpolation (vertex normals that cancel out) falls back to the geometric normal.
  if (!mesh_.normals.empty())
    if (const auto n = TriangleMesh::shadingNormal(face.n, Vec3(b0, b1, b2), face.ng))
      h.ns = n->dot(h.ng) >= 0 ? *n : Vec3(-*n);
  return h;
}

namespace {
RTCRayHit traceClosest(RTCScene scene, const Vec3& o, const Vec3& d, float tmax) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = o.x(), rh.ray.org_y = o.y(), rh.ray.org_z = o.z();
  rh.ray.dir_x = d.x(), rh.ray.dir_y = d.y(), rh.ray.dir_z = d.z();
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = tmax;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.ray.time = 0.0f;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &ctx, &rh);
  return rh;
}
}  // namespace

bool Scene::traceable(const Vec3& o, const Vec3& d, float tmax) const {
  const bool ok = o.allFinite() && d.allFinite() && tmax >= 0.0f;  // false for a NaN tmax too
  DCHECK(ok && "non-finite or inverted ray");
  if (!ok) skippedRays_.fetch_add(1, std::memory_order_relaxed);
  return ok;
}

float Scene::hitDistance(const Vec3& o, const Vec3& d, float tmax) const {
  if (!traceable(o, d, tmax)) return INFINITY;
  const RTCRayHit rh = traceClosest(scene_, o, d, tmax);
  return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? INFINITY : rh.ray.tfar;
}

RayHit Scene::traverse(const Vec3& o, const Vec3& d, float tmax) const {
  if (!traceable(o, d, tmax)) return {};
  const RTCRayHit rh = traceClosest(scene_, o, d, tmax);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return {};
  prefetchFace(rh.hit.primID);
  return {rh.hit.primID, rh.hit.u, rh.hit.v, rh.ray.tfar};
}

SurfaceHit Scene::surfaceAt(const RayHit& hit, const Vec3& o, const Vec3& d) const {
  // The hit point from the ray (no vertex fetch); Embree's t is accurate to a few ulps.
  SurfaceHit h = hitFromFace(hit.prim, hit.b1, hit.b2);
  h.t = hit.t;
  h.p = o + h.t * d;
  return h;
}

std::optional<SurfaceHit> Scene::intersect(const Vec3& o, const Vec3& d, float tmax) const {
  const RayHit hit = traverse(o, d, tmax);
  if (!hit.found()) return std::nullopt;
  return surfaceAt(hit, o, d);
}

bool Scene::occluded(const Vec3& o, const Vec3& d, float tmax) const {
  if (!traceable(o, d, tmax)) return true;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  r.org_x = o.x(), r.org_y = o.y(), r.org_z = o.z();
  r.dir_x = d.x(), r.dir_y = d.y(), r.dir_z = d.z();
  r.tnear = 0.0f;
  r.tfar = tmax;
  r.mask = 0xFFFFFFFFu;
  r.flags = 0;
  r.time = 0.0f;
  rtcOccluded1(scene_, &ctx, &r);
  return r.tfar < 0.0f;
}

Vec3 Scene::offsetOrigin(const SurfaceHit& hit, const Vec3& dir) {
  const float eps = rayEpsilon(hit.p);
  return hit.p + (dir.dot(hit.ng) >= 0 ? eps : -eps) * hit.ng;
}

}  // namespace relume
