#include "scene/appearance.h"

#include "core/error.h"
#include "io/image.h"
#include "io/json.h"

namespace relume {

Appearance::Appearance(int n)
    : names(n), roughness(n, 0.5f), specular(n, 0.5f), emission(n, Color::Zero()),
      albedoConstant(n, Color::Constant(0.5f)), albedoFromTexture(n, 0), emissionTextureOf(n, -1) {
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

namespace {

Color readColor(const Json& j, const char* key, const std::string& where) {
  const Json& v = j.at(key);
  if (v.is_number()) return Color::Constant(v.get<float>());
  if (!v.is_array() || v.size() != 3) fail("{}: '{}' must be a number or [r,g,b]", where, key);
  Color c;
  for (int k = 0; k < 3; ++k) {
    if (!v[k].is_number()) fail("{}: '{}' must contain numbers", where, key);
    c[k] = v[k].get<float>();
  }
  if (!isFinite(c)) fail("{}: '{}' is not finite", where, key);
  return c;
}

Texture readTexture(const std::filesystem::path& path) {
  const Image img = readImage(path);
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
  if (j.contains("diffuse")) fail("{}: 'diffuse' is no longer read; name the appearance 'model' (principled-v1 or gltf)", file);
  const std::string model = j.value("model", bsdfModelName(BsdfModel::PrincipledV1));
  if (model == bsdfModelName(BsdfModel::PrincipledV1)) a.model = BsdfModel::PrincipledV1;
  else if (model == bsdfModelName(BsdfModel::Gltf)) a.model = BsdfModel::Gltf;
  else fail("{}: 'model' must be principled-v1 or gltf, not '{}'", file, model);
  if (j.contains("albedo_texture")) {
    if (!s.mesh.hasUv()) fail("{}: 'albedo_texture' given but {} has no valid uv", file, s.meshPath.string());
    a.albedo = readTexture(dir / j["albedo_texture"].get<std::string>());
    std::fill(a.albedoFromTexture.begin(), a.albedoFromTexture.end(), 1);
  }
  if (j.contains("objects")) {
    if (!j["objects"].is_array()) fail("{}: 'objects' must be an array", file);
    for (size_t i = 0; i < j["objects"].size(); ++i) {
      const Json& o = j["objects"][i];
      const std::string where = fmt::format("{}: objects[{}]", file, i);
      if (!o.is_object() || !o.contains("id") || !o["id"].is_number_integer()) fail("{}: needs an integer 'id'", where);
      const int id = o["id"].get<int>();
      if (id < 0 || id >= a.objectCount()) {
        fail("{}: id {} not in the mesh (objects 0..{})", where, id, a.objectCount() - 1);
      }
      if (o.contains("name")) a.names[id] = o["name"].get<std::string>();
      if (o.contains("albedo")) {
        a.albedoConstant[id] = readColor(o, "albedo", where);
        a.albedoFromTexture[id] = 0;
      }
      a.roughness[id] = static_cast<float>(jsonNumberOr(o, "roughness", a.roughness[id], path));
      a.specular[id] = static_cast<float>(jsonNumberOr(o, "specular", a.specular[id], path));
      if (o.contains("emission")) a.emission[id] = readColor(o, "emission", where);
      if (a.emission[id].minCoeff() < 0) fail("{}: emission must be >= 0", where);
      if (o.contains("emission_texture")) {
        if (!s.mesh.hasUv()) fail("{}: emission_texture needs a mesh with uv", where);
        const Json& w = o["emission_window"];
        if (!w.is_array() || w.size() != 4) fail("{}: 'emission_window' must be [x0, y0, atlas_width, atlas_height]", where);
        Texture t = readTexture(dir / o["emission_texture"].get<std::string>());
        t.x0 = w[0].get<int>(), t.y0 = w[1].get<int>(), t.fullWidth = w[2].get<int>(), t.fullHeight = w[3].get<int>();
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
    Json obj{{"id", o}, {"name", a.names[o]}, {"roughness", a.roughness[o]}, {"specular", a.specular[o]},
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
