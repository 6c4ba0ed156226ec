// The appearance of every surface: what the renderer evaluates and what the optimiser changes.
// Per-object roughness/specular/emission, an albedo atlas texture (or per-object constants) and
// emission textures allocated only over emitter objects.
#pragma once
#include <filesystem>
#include <string>

#include "io/json.h"
#include "scene/mesh.h"
#include "scene/texture.h"

namespace relume {

// The scene's appearance model, each exactly one published BSDF (docs/user/scene-file.md):
// PrincipledV1 is Blender 2.8-3.x Principled BSDF in Cycles with metallic 0, Gltf the glTF 2.0
// metallic-roughness BRDF with KHR_materials_specular.
enum class BsdfModel { PrincipledV1, Gltf };
const char* bsdfModelName(BsdfModel m);

// alpha = r^2 is clamped at 1e-3 (r = 0.0316), where its gradient is 0: r_min sits just above.
inline constexpr float kRoughnessMin = 0.035f;

// The largest emitted radiance relume accepts anywhere (scene files, emission textures, edits and
// their emission_scale, gradcheck's --emission-scale) and the fit's upper bound on emission. Float
// sums of it cannot overflow: a path's squared radiance (1e8 times a throughput factor of up to
// 5e6, squared) summed over 2^30 samples stays below FLT_MAX (3.4e38); see
// docs/design/reliability.md, "Radiance bound".
inline constexpr float kMaxEmission = 1e8f;

struct Appearance {
  BsdfModel model = BsdfModel::PrincipledV1;
  std::vector<std::string> names;
  std::vector<float> roughness, specular;
  std::vector<Color> emission;        // Lambertian radiance per object (front side)
  std::vector<Color> albedoConstant;  // used where albedoFromTexture[o] == 0
  std::vector<uint8_t> albedoFromTexture;
  Texture albedo;                         // uv atlas, row 0 at the top
  std::vector<int> emissionTextureOf;     // per object: index into emissionTextures or -1
  std::vector<Texture> emissionTextures;  // windows of the atlas, one per textured emitter

  explicit Appearance(int objectCount = 0);
  int objectCount() const { return static_cast<int>(roughness.size()); }
  bool usesTexture(int object) const { return albedoFromTexture[object] != 0 && !albedo.empty(); }
  Color albedoAt(int object, const Vec2& uv) const {
    return usesTexture(object) ? albedo.lookup(uv) : albedoConstant[object];
  }
  // always_inline, as Texture::prefetch: else GCC deletes the call.
  [[gnu::always_inline]] void prefetchAlbedo(int object, const Vec2& uv) const {
    if (usesTexture(object)) albedo.prefetch(uv);
  }
  const Texture* emissionTexture(int object) const {
    return emissionTextureOf[object] >= 0 ? &emissionTextures[emissionTextureOf[object]] : nullptr;
  }
  // always_inline, as Texture::prefetch: else GCC deletes the call.
  [[gnu::always_inline]] void prefetchEmission(int object, const Vec2& uv) const {
    if (const Texture* t = emissionTexture(object)) t->prefetch(uv);
  }
  Color emissionAt(int object, const Vec2& uv) const {
    const Texture* t = emissionTexture(object);
    return t ? t->lookup(uv) : emission[object];
  }
  bool isEmissive(int object) const;
  // A new object with the defaults above and constant albedo; returns its id.
  int addObject(const std::string& name);
  // Average emitted radiance of an object (texture mean if textured): drives light selection.
  Color meanEmission(int object) const;
  // Largest emitted radiance of an object, any channel (any texel if textured).
  float maxEmission(int object) const;
};

struct SceneDescription {
  std::filesystem::path meshPath;
  TriangleMesh mesh;
  Appearance appearance;
};

// The constant material fields a JSON object names (albedo, roughness, specular, emission), each
// checked against its domain, written to object `id`; errors start with `where`. A constant
// albedo replaces the albedo texture on that object.
void readConstantFields(const Json& o, int id, const std::string& where, Appearance& a);

// Throws unless every object emits at most kMaxEmission; `where` says what set the emission (a file
// and field, an option).
void requireEmissionBound(const Appearance& a, const std::string& where);

// scene.json (schema: docs/user/scene-file.md). Throws relume::Error naming the file and field.
SceneDescription loadSceneFile(const std::filesystem::path& path);
// Writes scene.json plus textures next to it (albedo.exr, emission_<object>.exr) and the mesh (atomic).
void saveSceneFile(const std::filesystem::path& path, const SceneDescription& scene);

}  // namespace relume
