#include "scene/appearance.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "io/image.h"
#include "io/json.h"

namespace relume {

Appearance::Appearance(int n)
    : names(n),
      roughness(n, 0.5f),
      specular(n, 0.5f),
      emission(n, Color::Zero()),
      albedoConstant(n, Color::Constant(0.5f)),
      albedoFromTexture(n, 0),
      emissionTextureOf(n, -1) {
  for (int i = 0; i < n; ++i) names[i] = fmt::format("object{}", i);
}

const char* bsdfModelName(BsdfModel m) { return m == BsdfModel::PrincipledV1 ? "principled-v1" : "gltf"; }

bool Appearance::isEmissive(int object) const { return meanEmission(object).maxCoeff() > 0.0f; }

Color Appearance::meanEmission(int object) const {
  const Texture* t = emissionTexture(object);
  if (!t) return emission[object];
  Color sum = Color::Zero();
  for (uint32_t i = 0; i < t->texelCount(); ++i) sum += t->texel(i).max(0.0f);
  return sum / static_cast<float>(std::max<size_t>(1, t->texelCount()));
}

float Appearance::maxEmission(int object) const {
  const Texture* t = emissionTexture(object);
  if (!t) return emission[object].maxCoeff();
  return t->rgb.empty() ? 0.0f : *std::max_element(t->rgb.begin(), t->rgb.end());
}

void requireEmissionBound(const Appearance& a, const std::string& where) {
  for (int o = 0; o < a.objectCount(); ++o)
    if (const float e = a.maxEmission(o); !(e <= kMaxEmission))
      fail("{}: object {} ('{}') would emit {:g}, above the bound {:g} (docs/user/scene-file.md)", where, o, a.names[o],
           e, kMaxEmission);
}

namespace {

// Every number is checked in float, the precision it is used in (1e39 is finite as a double, not as a
// float). `range` describes [lo, hi] in the error.
constexpr const char* kEmissionRange = "in [0, 1e8] (the radiance bound)";

float floatIn(const Json& v, double lo, double hi, const char* range, const std::string& where,
              const std::string& field) {
  if (!v.is_number()) fail("{}: '{}' must be a number", where, field);
  const double d = v.get<double>();
  const float f = static_cast<float>(d);
  if (!std::isfinite(f) || !(f >= lo && f <= hi)) fail("{}: '{}' is {}, must be {}", where, field, d, range);
  return f;
}

Color readColor(const Json& j, const char* key, double lo, double hi, const char* range, const std::string& where) {
  const Json& v = j.at(key);
  if (v.is_number()) return Color::Constant(floatIn(v, lo, hi, range, where, key));
  if (!v.is_array() || v.size() != 3) fail("{}: '{}' must be a number or [r,g,b]", where, key);
  Color c;
  for (int k = 0; k < 3; ++k) c[k] = floatIn(v[k], lo, hi, range, where, fmt::format("{}[{}]", key, k));
  return c;
}

int intIn(const Json& v, int lo, int hi, const std::string& where, const std::string& field) {
  return static_cast<int>(jsonInteger(v, lo, hi, where, field));
}

// Texels are checked like the constants: every channel finite in [lo, hi].
Texture readTexture(const std::filesystem::path& path, double lo, double hi, const char* range) {
  ImageReadStats stats;
  const Image img = readImage(path, &stats);
  if (stats.nonFinitePixels)
    fail("{}: texel ({}, {}) is not finite, must be {}", path.string(), stats.nonFiniteIndex[0] % img.width,
         stats.nonFiniteIndex[0] / img.width, range);
  for (size_t i = 0; i < img.rgb.size(); ++i)
    if (!(img.rgb[i] >= lo && img.rgb[i] <= hi))
      fail("{}: texel ({}, {}) channel {} is {}, must be {}", path.string(), i / 3 % img.width, i / 3 / img.width,
           i % 3, img.rgb[i], range);
  Texture t(img.width, img.height);
  t.rgb = img.rgb;
  return t;
}

Image textureImage(const Texture& t) {
  Image img(t.width, t.height);
  img.rgb = t.rgb;
  return img;
}

}  // namespace

void readConstantFields(const Json& o, int id, const std::string& where, Appearance& a) {
  if (o.contains("albedo")) {
    a.albedoConstant[id] = readColor(o, "albedo", 0.0, 1.0, "in [0, 1]", where);
    a.albedoFromTexture[id] = 0;
  }
  if (o.contains("roughness"))
    a.roughness[id] = floatIn(o["roughness"], kRoughnessMin, 1.0, "in [0.035, 1]", where, "roughness");
  if (o.contains("specular")) a.specular[id] = floatIn(o["specular"], 0.0, 1.0, "in [0, 1]", where, "specular");
  if (o.contains("emission")) a.emission[id] = readColor(o, "emission", 0.0, kMaxEmission, kEmissionRange, where);
}

int Appearance::addObject(const std::string& name) {
  names.push_back(name);
  roughness.push_back(0.5f);
  specular.push_back(0.5f);
  emission.push_back(Color::Zero());
  albedoConstant.push_back(Color::Constant(0.5f));
  albedoFromTexture.push_back(0);
  emissionTextureOf.push_back(-1);
  return objectCount() - 1;
}

static SceneDescription parseSceneFile(const std::filesystem::path& path) {
  const std::string file = path.string();
  const Json j = readJson(path);
  if (!j.is_object() || !j.contains("mesh") || !j["mesh"].is_string()) fail("{}: missing 'mesh' path", file);
  const auto dir = path.parent_path();
  SceneDescription s;
  s.meshPath = dir / j["mesh"].get<std::string>();
  s.mesh = loadMesh(s.meshPath);
  Appearance& a = s.appearance;
  a = Appearance(s.mesh.objectCount);
  if (j.contains("diffuse"))
    fail("{}: 'diffuse' is no longer read; name the appearance 'model' (principled-v1 or gltf)", file);
  const std::string model = j.value("model", bsdfModelName(BsdfModel::PrincipledV1));
  if (model == bsdfModelName(BsdfModel::PrincipledV1))
    a.model = BsdfModel::PrincipledV1;
  else if (model == bsdfModelName(BsdfModel::Gltf))
    a.model = BsdfModel::Gltf;
  else
    fail("{}: 'model' must be principled-v1 or gltf, not '{}'", file, model);
  if (j.contains("albedo_texture")) {
    if (!s.mesh.hasUv()) fail("{}: 'albedo_texture' given but {} has no valid uv", file, s.meshPath.string());
    a.albedo = readTexture(dir / j["albedo_texture"].get<std::string>(), 0.0, 1.0, "in [0, 1] (albedo)");
    std::fill(a.albedoFromTexture.begin(), a.albedoFromTexture.end(), 1);
  }
  if (j.contains("objects")) {
    if (!j["objects"].is_array()) fail("{}: 'objects' must be an array", file);
    for (size_t i = 0; i < j["objects"].size(); ++i) {
      const Json& o = j["objects"][i];
      const std::string where = fmt::format("{}: objects[{}]", file, i);
      if (!o.is_object() || !o.contains("id") || !o["id"].is_number_integer()) fail("{}: needs an integer 'id'", where);
      const int id = intIn(o["id"], 0, std::numeric_limits<int>::max(), where, "id");
      if (id >= a.objectCount()) fail("{}: id {} not in the mesh (objects 0..{})", where, id, a.objectCount() - 1);
      if (o.contains("name")) a.names[id] = o["name"].get<std::string>();
      readConstantFields(o, id, where, a);
      if (o.contains("emission_texture")) {
        if (!s.mesh.hasUv()) fail("{}: emission_texture needs a mesh with uv", where);
        // contains() first: operator[] of a const json on a missing key is undefined behaviour.
        if (!o.contains("emission_window") || !o["emission_window"].is_array() || o["emission_window"].size() != 4)
          fail("{}: 'emission_window' must be [x0, y0, atlas_width, atlas_height]", where);
        const Json& w = o["emission_window"];
        Texture t = readTexture(dir / o["emission_texture"].get<std::string>(), 0.0, kMaxEmission, kEmissionRange);
        const int maxSide = std::numeric_limits<int>::max();
        t.x0 = intIn(w[0], 0, maxSide, where, "emission_window[0]"),
        t.y0 = intIn(w[1], 0, maxSide, where, "emission_window[1]");
        t.fullWidth = intIn(w[2], 1, maxSide, where, "emission_window[2]");
        t.fullHeight = intIn(w[3], 1, maxSide, where, "emission_window[3]");
        a.emissionTextureOf[id] = static_cast<int>(a.emissionTextures.size());
        a.emissionTextures.push_back(std::move(t));
      }
    }
  }
  return s;
}

void saveSceneFile(const std::filesystem::path& path, const SceneDescription& s) {
  const auto dir = path.parent_path();
  const Appearance& a = s.appearance;
  Json j;
  j["mesh"] = "mesh.ply";
  writePly(dir / "mesh.ply", s.mesh.toData());
  j["model"] = bsdfModelName(a.model);
  if (!a.albedo.empty()) {
    j["albedo_texture"] = "albedo.exr";
    writeExr(dir / "albedo.exr", textureImage(a.albedo));
  }
  Json objects = Json::array();
  for (int o = 0; o < a.objectCount(); ++o) {
    Json obj{{"id", o},
             {"name", a.names[o]},
             {"roughness", a.roughness[o]},
             {"specular", a.specular[o]},
             {"emission", {a.emission[o][0], a.emission[o][1], a.emission[o][2]}}};
    if (!a.usesTexture(o)) obj["albedo"] = {a.albedoConstant[o][0], a.albedoConstant[o][1], a.albedoConstant[o][2]};
    if (const Texture* t = a.emissionTexture(o)) {
      const std::string name = fmt::format("emission_{}.exr", o);
      obj["emission_texture"] = name;
      obj["emission_window"] = {t->x0, t->y0, t->fullWidth, t->fullHeight};
      writeExr(dir / name, textureImage(*t));
    }
    objects.push_back(obj);
  }
  j["objects"] = objects;
  writeJson(path, j);
}

SceneDescription loadSceneFile(const std::filesystem::path& path) {
  return withJsonErrors(path, [&] { return parseSceneFile(path); });
}

}  // namespace relume
