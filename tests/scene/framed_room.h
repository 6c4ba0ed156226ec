// Test mesh for the atlas on real-interior shapes: the procedural room plus 200 picture frames
// (flat rectangular rings, 40 x 30 cm with 2 cm bars, 8 triangles each: one hollow chart apiece)
// and 20000 separate 2-5 mm triangles (screws, chain links, sub-texel parts).
#pragma once
#include "core/rng.h"
#include "scenes/synth.h"

namespace relume {

inline TriangleMesh makeFramedRoom() {
  TriangleMesh room = makeSynthScene(SynthSceneKind::Room, 256).scene.mesh;
  room.uvs.clear();
  MeshData d = room.toData();
  d.normals.clear();
  Pcg32 rng(11);
  auto add = [&](const Vec3& a, const Vec3& b, const Vec3& c, int object) {
    const int base = static_cast<int>(d.positions.size());
    d.positions.insert(d.positions.end(), {a, b, c});
    d.triangles.push_back({base, base + 1, base + 2});
    d.faceObject.push_back(object);
  };
  for (int i = 0; i < 200; ++i) {
    const Vec3 at = rng.next3D();
    const Vec3 c(0.5f + 4 * at.x(), 0.5f + 1.5f * at.y(), 0.1f + 3 * at.z());
    const float w = 0.2f, h = 0.15f, bar = 0.02f;
    const Vec3 outer[4] = {c + Vec3(-w, -h, 0), c + Vec3(w, -h, 0), c + Vec3(w, h, 0), c + Vec3(-w, h, 0)};
    const Vec3 inner[4] = {c + Vec3(bar - w, bar - h, 0), c + Vec3(w - bar, bar - h, 0), c + Vec3(w - bar, h - bar, 0),
                           c + Vec3(bar - w, h - bar, 0)};
    const int base = static_cast<int>(d.positions.size());
    for (int k = 0; k < 4; ++k) d.positions.push_back(outer[k]);
    for (int k = 0; k < 4; ++k) d.positions.push_back(inner[k]);
    for (int k = 0; k < 4; ++k) {  // one mitred bar: two triangles
      const int o0 = base + k, o1 = base + (k + 1) % 4, i0 = o0 + 4, i1 = o1 + 4;
      d.triangles.push_back({o0, o1, i1}), d.triangles.push_back({o0, i1, i0});
      d.faceObject.push_back(6), d.faceObject.push_back(6);
    }
  }
  for (int i = 0; i < 20000; ++i) {
    const Vec3 at = rng.next3D();
    const Vec3 p(0.5f + 4 * at.x(), 0.1f + 2 * at.y(), 0.5f + 3 * at.z());
    const float s = 0.002f + 0.003f * rng.next1D();
    add(p, p + Vec3(s, 0, 0), p + Vec3(0, s, 0.3f * s), 7);
  }
  return buildMesh(d, "framed room");
}

}  // namespace relume
