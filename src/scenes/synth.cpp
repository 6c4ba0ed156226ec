#include "scenes/synth.h"

#include "io/json.h"

#include <spdlog/spdlog.h>

#include "core/error.h"
#include "core/rng.h"
#include "core/system.h"
#include "io/file_system.h"
#include "io/image.h"
#include "render/film.h"

namespace relume {

SynthSceneKind parseSynthScene(const std::string& name) {
  if (name == "room") return SynthSceneKind::Room;
  if (name == "cornell") return SynthSceneKind::Cornell;
  if (name == "furnace") return SynthSceneKind::Furnace;
  if (name == "scan") return SynthSceneKind::Scan;
  if (name == "lounge") return SynthSceneKind::Lounge;
  fail("unknown synthetic scene '{}' (room, cornell, furnace, scan, lounge)", name);
}

namespace {

// Albedo as a function of the chart's local metric coordinates (s, t) in metres.
using AlbedoPattern = std::function<Color(float s, float t)>;

// A rectangle of surface with its own chart: origin + s*axisS + t*axisT, s in [0,lenS], t in [0,lenT].
// Curved patches (the sphere) map (s,t) through `place`.
struct Patch {
  int object;
  float lenS, lenT;
  int segS = 1, segT = 1;
  std::function<Vec3(float, float)> place;
  AlbedoPattern albedo;
};

class SceneBuilder {
 public:
  // Quads are tessellated into cells of at most this size (metres), like a scanned mesh.
  explicit SceneBuilder(float cellSize = 1e9f) : cellSize_(cellSize) {}
  int addObject(const std::string& name, float roughness, float specular, Color emission = Color::Zero()) {
    names_.push_back(name);
    roughness_.push_back(roughness);
    specular_.push_back(specular);
    emission_.push_back(emission);
    return static_cast<int>(names_.size() - 1);
  }
  // Quad with normal axisS x axisT (counter-clockwise seen from the front).
  void quad(int object, const Vec3& origin, const Vec3& edgeS, const Vec3& edgeT, AlbedoPattern albedo) {
    const float ls = edgeS.norm(), lt = edgeT.norm();
    const Vec3 ds = edgeS / ls, dt = edgeT / lt;
    const int segS = std::max(1, static_cast<int>(std::ceil(ls / cellSize_)));
    const int segT = std::max(1, static_cast<int>(std::ceil(lt / cellSize_)));
    patches_.push_back({object, ls, lt, segS, segT, [=](float s, float t) { return Vec3(origin + s * ds + t * dt); },
                        std::move(albedo)});
  }
  // Axis-aligned box, outward normals; bottom face omitted when it rests on the floor.
  void box(int object, const Vec3& lo, const Vec3& hi, const AlbedoPattern& albedo, bool withBottom = false) {
    const Vec3 d = hi - lo;
    const Vec3 X(d.x(), 0, 0), Y(0, d.y(), 0), Z(0, 0, d.z());
    quad(object, lo + Y, Z, X, albedo);              // top (+y)
    if (withBottom) quad(object, lo, X, Z, albedo);  // bottom (-y)
    quad(object, lo, Y, X, albedo);                  // -z
    quad(object, lo + Z + X, Y, -X, albedo);         // +z
    quad(object, lo + Z, Y, -Z, albedo);             // -x
    quad(object, lo + X, Y, Z, albedo);              // +x
  }
  void sphere(int object, const Vec3& centre, float radius, bool inward, AlbedoPattern albedo, int seg = 48) {
    const float sign = inward ? -1.0f : 1.0f;
    patches_.push_back({object, 2 * kPi * radius, kPi * radius, seg, seg / 2,
                        [=](float s, float t) {
                          const float phi = sign * s / radius, theta = t / radius;
                          return Vec3(centre + radius * Vec3(std::sin(theta) * std::cos(phi), std::cos(theta),
                                                             std::sin(theta) * std::sin(phi)));
                        },
                        std::move(albedo)});
  }

  // Packs one chart per patch into a square atlas (shelf packing, 2-texel gutter at `resolution`),
  // tessellates, and bakes the albedo texture including gutters (clamped to the chart).
  SceneDescription build(int resolution) {
    const int gutter = 2;
    // Largest texel density whose shelf packing fits.
    double lo = 1e-3, hi = 1e5;
    for (int it = 0; it < 60; ++it) {
      const double mid = std::sqrt(lo * hi);
      (pack(mid, resolution, gutter) ? lo : hi) = mid;
    }
    if (!pack(lo, resolution, gutter))
      fail("atlas resolution {} is too small for {} charts with {}-texel gutters", resolution, patches_.size(), gutter);
    SceneDescription out;
    TriangleMesh& m = out.mesh;
    m.objectCount = static_cast<int>(names_.size());
    Appearance a(m.objectCount);
    a.names = names_;
    a.roughness = roughness_;
    a.specular = specular_;
    a.emission = emission_;
    a.albedo = Texture(resolution, resolution, Color::Constant(0.0f));
    std::fill(a.albedoFromTexture.begin(), a.albedoFromTexture.end(), 1);
    const float R = static_cast<float>(resolution);
    for (size_t i = 0; i < patches_.size(); ++i) {
      const Patch& p = patches_[i];
      const Placement& pl = placement_[i];
      const int base = static_cast<int>(m.positions.size());
      for (int j = 0; j <= p.segT; ++j)
        for (int k = 0; k <= p.segS; ++k) {
          const float s = p.lenS * k / p.segS, t = p.lenT * j / p.segT;
          m.positions.push_back(p.place(s, t));
          m.uvs.emplace_back((pl.x + gutter + s * pl.density) / R, (pl.y + gutter + t * pl.density) / R);
        }
      for (int j = 0; j < p.segT; ++j)
        for (int k = 0; k < p.segS; ++k) {
          const int v00 = base + j * (p.segS + 1) + k, v10 = v00 + 1, v01 = v00 + p.segS + 1, v11 = v01 + 1;
          // Sphere rows at the poles collapse one triangle of each quad: leave those out.
          for (const Eigen::Vector3i& t : {Eigen::Vector3i(v00, v10, v11), Eigen::Vector3i(v00, v11, v01)}) {
            const Vec3 e1 = m.positions[t[1]] - m.positions[t[0]], e2 = m.positions[t[2]] - m.positions[t[0]];
            if (e1.cross(e2).norm() <= 1e-10f) continue;
            m.triangles.push_back(t);
            m.faceObject.push_back(p.object);
          }
        }
      for (int y = pl.y; y < pl.y + pl.h; ++y)
        for (int x = pl.x; x < pl.x + pl.w; ++x) {
          const float s = std::clamp((x + 0.5f - pl.x - gutter) / pl.density, 0.0f, p.lenS);
          const float t = std::clamp((y + 0.5f - pl.y - gutter) / pl.density, 0.0f, p.lenT);
          const Color c = p.albedo(s, t);
          float* px = &a.albedo.rgb[3 * (static_cast<size_t>(y) * resolution + x)];
          px[0] = c[0], px[1] = c[1], px[2] = c[2];
        }
    }
    MeshData data = m.toData();
    out.mesh = buildMesh(std::move(data), "synthetic scene");
    out.appearance = std::move(a);
    return out;
  }

 private:
  struct Placement {
    int x = 0, y = 0, w = 0, h = 0;
    float density = 0;
  };
  bool pack(double density, int resolution, int gutter) {
    placement_.assign(patches_.size(), {});
    std::vector<size_t> order(patches_.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    for (size_t i = 0; i < patches_.size(); ++i) {
      placement_[i].w = static_cast<int>(std::ceil(patches_[i].lenS * density)) + 2 * gutter;
      placement_[i].h = static_cast<int>(std::ceil(patches_[i].lenT * density)) + 2 * gutter;
      placement_[i].density = static_cast<float>(density);
    }
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return placement_[a].h > placement_[b].h; });
    int x = 0, y = 0, rowH = 0;
    for (size_t i : order) {
      Placement& p = placement_[i];
      if (p.w > resolution) return false;
      if (x + p.w > resolution) x = 0, y += rowH, rowH = 0;
      p.x = x, p.y = y;
      x += p.w;
      rowH = std::max(rowH, p.h);
      if (y + p.h > resolution) return false;
    }
    return true;
  }
  float cellSize_;
  std::vector<std::string> names_;
  std::vector<float> roughness_, specular_;
  std::vector<Color> emission_;
  std::vector<Patch> patches_;
  std::vector<Placement> placement_;
};

AlbedoPattern constant(const Color& c) {
  return [c](float, float) { return c; };
}
float hash01(uint64_t a, uint64_t b) { return static_cast<float>(mix64(hashTuple({a, b})) >> 40) * 0x1p-24f; }

constexpr float kRoomX = 5.0f, kRoomY = 2.7f, kRoomZ = 4.0f;

// The kRoom box, walls facing in: each object and its albedo.
struct Shell {
  int floor, ceiling, wallZ0, walls;  // walls: the other three
  AlbedoPattern floorAlbedo, ceilingAlbedo, wallZ0Albedo, wallZMaxAlbedo, wallX0Albedo, wallXMaxAlbedo;
};

void addShell(SceneBuilder& b, const Shell& s) {
  const Vec3 X(kRoomX, 0, 0), Y(0, kRoomY, 0), Z(0, 0, kRoomZ);
  b.quad(s.floor, Vec3::Zero(), Z, X, s.floorAlbedo);    // normal +y
  b.quad(s.ceiling, Y, X, Z, s.ceilingAlbedo);           // normal -y
  b.quad(s.wallZ0, Vec3::Zero(), X, Y, s.wallZ0Albedo);  // z=0, normal +z
  b.quad(s.walls, Z + X, -X, Y, s.wallZMaxAlbedo);       // z=max, normal -z
  b.quad(s.walls, Z, -Z, Y, s.wallX0Albedo);             // x=0, normal +x
  b.quad(s.walls, X, Z, Y, s.wallXMaxAlbedo);            // x=max, normal -x
}

SceneDescription buildRoom(int resolution, float cellSize = 0.085f) {  // ~35k triangles, a coarse scan
  SceneBuilder b(cellSize);
  // Wooden planks: 0.2 m wide, random tone per plank, darker seams.
  const AlbedoPattern planks = [](float s, float t) -> Color {
    const int plank = static_cast<int>(s / 0.2f);
    const float tone = 0.75f + 0.5f * hash01(plank, static_cast<uint64_t>((t + plank * 0.37f) / 1.2f));
    const float seam = std::fmod(s, 0.2f) < 0.01f ? 0.5f : 1.0f;
    return Color(0.45f, 0.30f, 0.18f) * tone * seam;
  };
  const AlbedoPattern wallpaper = [](float s, float t) -> Color {
    return std::fmod(s, 0.3f) < 0.15f ? Color(0.75f, 0.72f, 0.62f) : Color(0.55f, 0.62f, 0.70f);
  };
  const AlbedoPattern rug = [](float s, float t) -> Color {
    const float d = std::min(std::min(s, 1.1f - s), std::min(t, 1.6f - t));
    const int ring = static_cast<int>(d / 0.12f);
    static const Color palette[] = {{0.55f, 0.10f, 0.08f}, {0.85f, 0.70f, 0.35f}, {0.12f, 0.20f, 0.45f}};
    return palette[ring % 3];
  };
  const AlbedoPattern painting = [](float s, float t) -> Color {
    const int cx = static_cast<int>(s / 0.25f), cy = static_cast<int>(t / 0.25f);
    return Color(0.2f + 0.7f * hash01(cx, cy), 0.2f + 0.7f * hash01(cx + 7, cy), 0.2f + 0.7f * hash01(cx, cy + 11));
  };
  const int floor = b.addObject("floor", 0.35f, 0.5f);
  const int ceiling = b.addObject("ceiling", 0.9f, 0.2f);
  const int walls = b.addObject("walls", 0.8f, 0.3f);
  const int wallPaper = b.addObject("wallpaper_wall", 0.7f, 0.4f);
  const int lightA = b.addObject("ceiling_light_a", 0.9f, 0.0f, Color(14.0f, 12.5f, 10.0f));
  const int lightB = b.addObject("ceiling_light_b", 0.9f, 0.0f, Color(10.0f, 11.0f, 13.0f));
  const int rugId = b.addObject("rug", 0.95f, 0.1f);
  const int table = b.addObject("table", 0.2f, 0.7f);
  const int cabinet = b.addObject("cabinet", 0.5f, 0.5f);
  const int shelf = b.addObject("shelf", 0.65f, 0.35f);
  const int sofa = b.addObject("sofa", 0.9f, 0.15f);
  const int ball = b.addObject("glossy_ball", 0.1f, 1.0f);
  const int cube = b.addObject("cube", 0.3f, 0.8f);
  const int frame = b.addObject("painting", 0.6f, 0.5f);

  addShell(b, {floor, ceiling, wallPaper, walls, planks, constant({0.85f, 0.85f, 0.83f}), wallpaper,
               constant({0.70f, 0.68f, 0.64f}), constant({0.62f, 0.66f, 0.60f}), constant({0.70f, 0.68f, 0.64f})});
  const float ly = kRoomY - 0.01f;
  b.quad(lightA, Vec3(1.2f, ly, 1.6f), Vec3(0.9f, 0, 0), Vec3(0, 0, 0.45f), constant({0.9f, 0.9f, 0.9f}));
  b.quad(lightB, Vec3(3.0f, ly, 2.2f), Vec3(0.9f, 0, 0), Vec3(0, 0, 0.45f), constant({0.9f, 0.9f, 0.9f}));
  b.quad(rugId, Vec3(1.7f, 0.005f, 2.6f), Vec3(0, 0, 1.1f), Vec3(1.6f, 0, 0), rug);
  b.box(table, Vec3(2.0f, 0.70f, 1.3f), Vec3(3.2f, 0.75f, 2.1f), constant({0.35f, 0.22f, 0.12f}), true);
  for (const Vec3& leg : {Vec3(2.05f, 0, 1.35f), Vec3(3.1f, 0, 1.35f), Vec3(2.05f, 0, 2.0f), Vec3(3.1f, 0, 2.0f)})
    b.box(table, leg, leg + Vec3(0.05f, 0.70f, 0.05f), constant({0.35f, 0.22f, 0.12f}));
  b.box(cabinet, Vec3(4.3f, 0, 0.3f), Vec3(4.9f, 1.1f, 1.3f), constant({0.20f, 0.35f, 0.30f}));
  b.box(shelf, Vec3(0.1f, 0, 0.8f), Vec3(0.5f, 1.9f, 2.2f), constant({0.60f, 0.55f, 0.45f}));
  b.box(sofa, Vec3(1.0f, 0, 3.3f), Vec3(3.4f, 0.45f, 3.9f), constant({0.45f, 0.15f, 0.12f}));
  b.box(sofa, Vec3(1.0f, 0.45f, 3.75f), Vec3(3.4f, 0.9f, 3.9f), constant({0.45f, 0.15f, 0.12f}));
  b.sphere(ball, Vec3(2.6f, 0.95f, 1.7f), 0.2f, false, constant({0.15f, 0.25f, 0.65f}));
  b.box(cube, Vec3(4.0f, 0, 2.8f), Vec3(4.45f, 0.45f, 3.25f), constant({0.75f, 0.70f, 0.25f}));
  b.quad(frame, Vec3(kRoomX - 0.01f, 1.1f, 1.8f), Vec3(0, 0, 1.0f), Vec3(0, 0.7f, 0), painting);
  return b.build(resolution);
}

SceneDescription buildLounge(int resolution) {
  SceneBuilder b(0.1f);
  const int floor = b.addObject("floor", 0.4f, 0.5f);
  const int ceiling = b.addObject("ceiling", 0.9f, 0.2f);
  const int walls = b.addObject("walls", 0.85f, 0.3f);
  const int windowA = b.addObject("window_a", 0.9f, 0.0f, Color(6.0f, 7.0f, 9.0f));
  const int windowB = b.addObject("window_b", 0.9f, 0.0f, Color(5.0f, 6.0f, 8.0f));
  const int lamp = b.addObject("pendant_lamp", 0.9f, 0.0f, Color(60.0f, 50.0f, 36.0f));
  const int table = b.addObject("red_glossy_table", 0.08f, 1.0f);
  const int sofa = b.addObject("white_sofa", 0.8f, 0.3f);
  const int cabinet = b.addObject("white_cabinet", 0.6f, 0.5f);
  const int rugId = b.addObject("rug", 0.95f, 0.1f);
  const AlbedoPattern planks = [](float s, float t) -> Color {
    const int plank = static_cast<int>(s / 0.2f);
    return Color(0.42f, 0.30f, 0.20f) * (0.8f + 0.4f * hash01(plank, static_cast<uint64_t>(t / 1.5f)));
  };
  const AlbedoPattern warmWhite = constant({0.78f, 0.76f, 0.72f});
  addShell(b, {floor, ceiling, walls, walls, planks, constant({0.85f, 0.85f, 0.83f}), warmWhite, warmWhite,
               constant({0.80f, 0.80f, 0.78f}), warmWhite});
  // Window panes on the x = 0 wall, facing into the room: glass, which transmits the sky's light
  // and reflects little of the room's.
  b.quad(windowA, Vec3(0.01f, 0.9f, 0.5f), Vec3(0, 1.2f, 0), Vec3(0, 0, 1.0f), constant({0.05f, 0.05f, 0.05f}));
  b.quad(windowB, Vec3(0.01f, 0.9f, 2.3f), Vec3(0, 1.2f, 0), Vec3(0, 0, 1.0f), constant({0.05f, 0.05f, 0.05f}));
  b.box(lamp, Vec3(3.2f, 1.75f, 1.6f), Vec3(3.4f, 1.9f, 1.8f), constant({0.9f, 0.9f, 0.9f}), true);
  b.box(table, Vec3(2.7f, 0.70f, 1.2f), Vec3(3.9f, 0.75f, 2.2f), constant({0.55f, 0.06f, 0.05f}), true);
  for (const Vec3& leg : {Vec3(2.75f, 0, 1.25f), Vec3(3.8f, 0, 1.25f), Vec3(2.75f, 0, 2.1f), Vec3(3.8f, 0, 2.1f)})
    b.box(table, leg, leg + Vec3(0.05f, 0.70f, 0.05f), constant({0.55f, 0.06f, 0.05f}));
  b.box(sofa, Vec3(1.4f, 0, 3.3f), Vec3(3.6f, 0.45f, 3.95f), constant({0.95f, 0.95f, 0.95f}));
  b.box(sofa, Vec3(1.4f, 0.45f, 3.75f), Vec3(3.6f, 0.9f, 3.95f), constant({0.95f, 0.95f, 0.95f}));
  b.box(cabinet, Vec3(4.3f, 0, 0.3f), Vec3(4.95f, 1.1f, 1.3f), constant({0.92f, 0.92f, 0.92f}));
  b.quad(rugId, Vec3(1.2f, 0.005f, 1.0f), Vec3(0, 0, 1.8f), Vec3(1.4f, 0, 0), constant({0.25f, 0.12f, 0.10f}));
  return b.build(resolution);
}

SceneDescription buildCornell(int resolution) {
  SceneBuilder b;
  const int white = b.addObject("white", 0.8f, 0.2f), red = b.addObject("red", 0.8f, 0.2f),
            green = b.addObject("green", 0.8f, 0.2f), light = b.addObject("light", 1.0f, 0.0f, Color(17, 12, 4)),
            tall = b.addObject("tall_box", 0.3f, 0.6f), shortBox = b.addObject("short_box", 0.6f, 0.4f);
  const float s = 2.0f;
  const Vec3 X(s, 0, 0), Y(0, s, 0), Z(0, 0, s);
  b.quad(white, Vec3::Zero(), Z, X, constant({0.73f, 0.73f, 0.73f}));  // floor
  b.quad(white, Y, X, Z, constant({0.73f, 0.73f, 0.73f}));             // ceiling
  b.quad(white, Vec3::Zero(), X, Y, constant({0.73f, 0.73f, 0.73f}));  // back (z=0)
  b.quad(white, Z + X, -X, Y, constant({0.73f, 0.73f, 0.73f}));        // front (closed room)
  b.quad(red, Z, -Z, Y, constant({0.63f, 0.06f, 0.05f}));              // x=0
  b.quad(green, X, Z, Y, constant({0.14f, 0.45f, 0.09f}));             // x=s
  b.quad(light, Vec3(0.75f, s - 0.005f, 0.8f), Vec3(0.5f, 0, 0), Vec3(0, 0, 0.4f), constant({0.8f, 0.8f, 0.8f}));
  b.box(tall, Vec3(0.35f, 0, 0.5f), Vec3(0.9f, 1.2f, 1.05f), constant({0.73f, 0.73f, 0.73f}));
  b.box(shortBox, Vec3(1.1f, 0, 1.0f), Vec3(1.65f, 0.6f, 1.55f), constant({0.73f, 0.73f, 0.73f}));
  return b.build(resolution);
}

SceneDescription buildFurnace(int resolution) {
  SceneBuilder b;
  const int shell = b.addObject("shell", 1.0f, 0.0f, Color::Constant(1.0f));
  b.sphere(shell, Vec3::Zero(), 1.0f, true, constant({0.5f, 0.5f, 0.5f}), 32);
  return b.build(resolution);
}

}  // namespace

SynthScene makeSynthScene(SynthSceneKind kind, int atlasResolution, size_t scanTriangles) {
  switch (kind) {
    case SynthSceneKind::Room:
      return {kind, buildRoom(atlasResolution)};
    case SynthSceneKind::Scan: {
      // Same objects and materials as the room; each object's albedo is its texture's mean.
      SceneDescription room = buildRoom(atlasResolution);
      Appearance& a = room.appearance;
      std::vector<Eigen::Array4d> mean(a.objectCount(), Eigen::Array4d::Zero());
      for (size_t f = 0; f < room.mesh.triangles.size(); ++f) {
        const auto& t = room.mesh.triangles[f];
        const Color c = a.albedo.lookup(Vec2((room.mesh.uvs[t[0]] + room.mesh.uvs[t[1]] + room.mesh.uvs[t[2]]) / 3.0f));
        mean[room.mesh.faceObject[f]] += Eigen::Array4d(c[0], c[1], c[2], 1.0) * room.mesh.faceArea[f];
      }
      for (int o = 0; o < a.objectCount(); ++o)
        a.albedoConstant[o] =
            mean[o][3] > 0 ? Color((mean[o].head<3>() / mean[o][3]).cast<float>()) : Color::Constant(0.5f);
      std::fill(a.albedoFromTexture.begin(), a.albedoFromTexture.end(), 0);
      a.albedo = Texture();
      room.mesh = makeScanLikeRoom(scanTriangles, 0.004f);
      return {kind, std::move(room)};
    }
    case SynthSceneKind::Cornell:
      return {kind, buildCornell(atlasResolution)};
    case SynthSceneKind::Furnace:
      return {kind, buildFurnace(atlasResolution)};
    case SynthSceneKind::Lounge:
      return {kind, buildLounge(atlasResolution)};
  }
  fail("bad synthetic scene kind");
}

TriangleMesh makeScanLikeRoom(size_t targetTriangles, float noiseMetres) {
  // Triangle count scales with 1/cell^2; 0.085 m cells give ~35k.
  const float cell = 0.085f * std::sqrt(32000.0f / static_cast<float>(std::max<size_t>(targetTriangles, 1000)));
  TriangleMesh m = buildRoom(2048, cell).mesh;
  for (Vec3& p : m.positions) {
    const Eigen::Vector3i q = (p / 1e-4f).array().round().cast<int>();  // coincident vertices move together
    const uint64_t h =
        hashTuple({static_cast<uint64_t>(q.x()), static_cast<uint64_t>(q.y()), static_cast<uint64_t>(q.z())});
    Pcg32 rng(h);
    const Vec3 u = rng.next3D();
    p += noiseMetres * Vec3(2 * u.x() - 1, 2 * u.y() - 1, 2 * u.z() - 1);
  }
  m.uvs.clear();
  return buildMesh(m.toData(), "scan-like room");
}

std::vector<Camera> synthCameraPath(SynthSceneKind kind, int frames, int width, int height, double phase) {
  std::vector<Camera> cams;
  const float hfov = 75.0f * kPi / 180.0f;
  for (int i = 0; i < frames; ++i) {
    const double u = (i + phase) / std::max(frames, 1);
    const double a = 2.0 * kPi * u;
    Vec3 pos, look;
    if (kind == SynthSceneKind::Furnace) {
      pos = Vec3(0.1f * std::cos(a), 0.05f * std::sin(2 * a), 0.1f * std::sin(a));
      look = Vec3(std::cos(a + 1), 0.3f * std::sin(3 * a), std::sin(a + 1));
    } else if (kind == SynthSceneKind::Cornell) {
      pos = Vec3(1.0f + 0.3f * std::cos(a), 1.0f + 0.15f * std::sin(2 * a), 1.85f);
      look = Vec3(0.25f * std::sin(a), 0.15f * std::sin(3 * a + 0.5f), -1.0f);
    } else {  // room, scan and lounge
      // Loop around the room centre looking across it at a target that sweeps the far walls,
      // from the floor up to the ceiling lights.
      pos = Vec3(2.5f + 1.3f * std::cos(a) + 0.03f * std::sin(7 * a), 1.45f + 0.08f * std::sin(5 * a),
                 2.0f + 0.9f * std::sin(a) + 0.03f * std::cos(9 * a));
      const double b = a + kPi + 0.8 * std::sin(2 * a);
      const Vec3 target(2.5f + 2.2f * std::cos(b), 1.3f + 1.25f * std::sin(3 * a + 0.3), 2.0f + 1.8f * std::sin(b));
      look = target - pos;
    }
    Camera c;
    c.width = width, c.height = height;
    c.fx = c.fy = 0.5f * width / std::tan(0.5f * hfov);
    c.cx = 0.5f * width, c.cy = 0.5f * height;
    const Vec3 fwd = look.normalized();
    const Vec3 right = fwd.cross(Vec3(0, 1, 0)).normalized();  // x right
    const Vec3 down = fwd.cross(right);                        // y down (OpenCV)
    c.rotation.col(0) = right;
    c.rotation.col(1) = down;
    c.rotation.col(2) = fwd;
    c.position = pos;
    cams.push_back(c);
  }
  return cams;
}

namespace {

// mesh.ply: the true mesh, or with imperfections a scanned-looking one (the clean capture's mesh
// kept as gt/mesh_clean.ply) and, if asked, without the segmentation. Returns the largest vertex offset.
double writeCaptureMesh(const SynthCaptureOptions& o, const SceneDescription& gt) {
  MeshData capMesh = gt.mesh.toData();
  if (!o.withUv) capMesh.uvs.clear();
  if (!o.imperfections || (!o.imperfections->meshNoise && o.imperfections->absentObject.empty()))
    std::filesystem::remove(o.out / "gt" / "mesh_clean.ply");  // an earlier capture's
  if (o.imperfections)
    return writeFlawedMesh(*o.imperfections, std::move(capMesh), gt.appearance.names, o.out, o.seed);
  writePly(o.out / "mesh.ply", capMesh);
  return 0;
}

// objects.json: the segmentation's names, as a capture would carry them (none with segmentation=none).
void writeObjectNames(const SynthCaptureOptions& o, const Appearance& a) {
  if (o.imperfections && !o.imperfections->segmentation) {
    std::filesystem::remove(o.out / "objects.json");  // an earlier capture's in the same folder
    return;
  }
  Json objects = Json::array();
  for (int id = 0; id < a.objectCount(); ++id) objects.push_back({{"id", id}, {"name", a.names[id]}});
  writeJson(o.out / "objects.json", Json{{"objects", objects}});
}

}  // namespace

int writeSynthCapture(const SynthCaptureOptions& o) {
  const SynthScene synth = makeSynthScene(o.kind, o.atlasResolution, o.scanTriangles);
  const SceneDescription& gt = synth.scene;
  // The cameras of a walk through the scene (phase 0: the training frames; 0.5: the held-out
  // ones, between them), forming their pixels with the capture's filter.
  const auto cameras = [&](int count, int width, int height, double phase) {
    std::vector<Camera> cams = synthCameraPath(o.kind, count, width, height, phase);
    for (Camera& cam : cams) cam.filter = o.pixelFilter;
    return cams;
  };
  const std::vector<Camera> walk = cameras(o.frames, o.width, o.height, 0.0);
  // The training frames' flaws, planned before anything is written (a spec that leaves no frame fails).
  std::vector<FrameImperfection> plan;
  if (o.imperfections) {
    const std::string& unseen = o.imperfections->unseenObject;
    const std::vector<uint8_t> showsUnseen =
        unseen.empty() ? std::vector<uint8_t>{}
                       : camerasShowing(gt.mesh.toData(), namedObject("unseen", unseen, gt.appearance.names), walk);
    plan = planFrameImperfections(*o.imperfections, walk, o.seed, showsUnseen);
  }
  createDirectories(o.out / "gt");
  saveSceneFile(o.out / "gt" / "scene.json", gt);
  const double largestVertexOffset = writeCaptureMesh(o, gt);
  writeObjectNames(o, gt.appearance);
  if (!o.imperfections) std::filesystem::remove(o.out / "gt" / "imperfections.json");  // an earlier capture's

  Scene scene(gt.mesh);
  LightSampler lights(scene, gt.appearance);
  RenderOptions ro;
  ro.path.maxDepth = o.maxDepth;
  int rendered = 0;
  const int testWidth = o.testWidth > 0 ? o.testWidth : o.width,
            testHeight = o.testHeight > 0 ? o.testHeight : o.height;
  for (const auto& [folder, json, count, phase, spp, width, height] :
       {std::tuple{"images", "transforms.json", o.frames, 0.0, o.spp, o.width, o.height},
        std::tuple{"test", "transforms_test.json", o.testFrames, 0.5, o.testSpp, testWidth, testHeight}}) {
    ro.spp = spp;
    std::vector<Frame> frames;
    // Only the training frames have flaws: the held-out ones are the judge.
    const bool training = std::string(folder) == "images";
    const std::vector<Camera> cams = training ? walk : cameras(count, width, height, phase);
    const ImperfectionSpec* flaws = training && o.imperfections ? &*o.imperfections : nullptr;
    Progress progress(training ? "synth frames" : "synth held-out", cams.size());
    for (size_t i = 0; i < cams.size(); ++i) {
      const std::filesystem::path exrPath = o.out / folder / fmt::format("frame_{:04d}.exr", i);
      if (flaws && plan[i].leftOut) {  // not rendered; an earlier capture's files go
        for (const char* ext : {".exr", ".png"})
          std::filesystem::remove(std::filesystem::path(exrPath).replace_extension(ext));
        progress.advance();
        continue;
      }
      ro.seed = hashTuple({o.seed, static_cast<uint64_t>(phase * 2), i});
      const RenderResult r = renderImage(scene, gt.appearance, lights, cams[i], ro);
      Frame f;
      if (flaws) {
        f = writeFlawedFrame(*flaws, plan[i], o.seed, exrPath, r.color);
      } else {
        f.camera = cams[i];
        f.image = exrPath;
        writeExr(f.image, r.color);
      }
      frames.push_back(f);
      ++rendered;
      spdlog::info("{} {}/{} rendered ({:.1f}s, {:.2f} Mrays/s)", folder, i + 1, cams.size(), r.stats.seconds,
                   r.stats.rays / r.stats.seconds * 1e-6);
      progress.advance();
    }
    // Rendered poses are exact unless the imperfections moved them.
    writeTransforms(o.out / json, frames, !(flaws && flaws->pose));
  }
  if (o.imperfections)
    writeJson(o.out / "gt" / "imperfections.json",
              imperfectionsJson(*o.imperfections, o.seed, plan, largestVertexOffset));
  return rendered;
}

}  // namespace relume
