#include "scene/scene.h"

#include <spdlog/spdlog.h>

#include "core/error.h"

namespace relume {
namespace {
void embreeError(void*, RTCError code, const char* message) {
  spdlog::error("embree error {}: {}", static_cast<int>(code), message ? message : "");
}
}  // namespace

Scene::Scene(TriangleMesh mesh, SceneOptions options) : mesh_(std::move(mesh)) {
  device_ = rtcNewDevice(nullptr);
  if (!device_) fail("cannot create Embree device (error {})", static_cast<int>(rtcGetDeviceError(nullptr)));
  rtcSetDeviceErrorFunction(device_, embreeError, nullptr);
  scene_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
  rtcSetSceneFlags(scene_, options.robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
  RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
  vertexBuffer_.resize(mesh_.positions.size() * 3 + 1);
  Eigen::AlignedBox3f box;
  for (size_t i = 0; i < mesh_.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) vertexBuffer_[3 * i + k] = mesh_.positions[i][k];
    box.extend(mesh_.positions[i]);
  }
  radius_ = 0.5f * box.diagonal().norm();
  rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertexBuffer_.data(), 0,
                             3 * sizeof(float), mesh_.positions.size());
  rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh_.triangles.data(), 0,
                             sizeof(Eigen::Vector3i), mesh_.triangles.size());
  rtcCommitGeometry(geom);
  rtcAttachGeometry(scene_, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene_);
}

Scene::~Scene() {
  if (scene_) rtcReleaseScene(scene_);
  if (device_) rtcReleaseDevice(device_);
}

SurfaceHit Scene::surfacePoint(uint32_t prim, float b1, float b2) const {
  const auto& tri = mesh_.triangles[prim];
  const float b0 = 1.0f - b1 - b2;
  SurfaceHit h;
  h.prim = prim;
  h.object = mesh_.faceObject[prim];
  h.p = b0 * mesh_.positions[tri[0]] + b1 * mesh_.positions[tri[1]] + b2 * mesh_.positions[tri[2]];
  h.ng = mesh_.faceNormal(prim);
  h.ns = h.ng;
  if (!mesh_.normals.empty()) {
    const Vec3 n = b0 * mesh_.normals[tri[0]] + b1 * mesh_.normals[tri[1]] + b2 * mesh_.normals[tri[2]];
    const float len = n.norm();
    if (len > 1e-6f) h.ns = n.dot(h.ng) >= 0 ? Vec3(n / len) : Vec3(-n / len);
  }
  h.uv = mesh_.hasUv() ? Vec2(b0 * mesh_.uvs[tri[0]] + b1 * mesh_.uvs[tri[1]] + b2 * mesh_.uvs[tri[2]]) : Vec2::Zero();
  return h;
}

std::optional<SurfaceHit> Scene::intersect(const Vec3& o, const Vec3& d, float tmax) const {
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
  rtcIntersect1(scene_, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return std::nullopt;
  SurfaceHit h = surfacePoint(rh.hit.primID, rh.hit.u, rh.hit.v);
  h.t = rh.ray.tfar;
  return h;
}

bool Scene::occluded(const Vec3& o, const Vec3& d, float tmax) const {
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
