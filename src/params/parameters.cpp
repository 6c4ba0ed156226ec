#include "params/parameters.h"

#include "core/error.h"

namespace relume {

const char* paramKindName(ParamKind kind) {
  switch (kind) {
    case ParamKind::Albedo:
      return "albedo";
    case ParamKind::Roughness:
      return "roughness";
    case ParamKind::Specular:
      return "specular";
    case ParamKind::Emission:
      return "emission";
    case ParamKind::EmissionTexture:
      return "emission_tex";
  }
  return "";
}

ParamKind parseParamKind(const std::string& name) {
  for (ParamKind k : kAllParamKinds)
    if (name == paramKindName(k)) return k;
  fail("unknown parameter kind '{}' (albedo, roughness, specular, emission, emission_tex)", name);
}

std::string ParamRef::label() const {
  const char* rgb = "rgb";
  switch (kind) {
    case ParamKind::Albedo:
      return fmt::format("albedo[texel {}].{}", texel, rgb[channel]);
    case ParamKind::Roughness:
      return fmt::format("roughness[obj {}]", object);
    case ParamKind::Specular:
      return fmt::format("specular[obj {}]", object);
    case ParamKind::Emission:
      return fmt::format("emission[obj {}].{}", object, rgb[channel]);
    case ParamKind::EmissionTexture:
      return fmt::format("emission_tex[obj {} texel {}].{}", object, texel, rgb[channel]);
  }
  return "";
}

std::string ParamGroup::name() const {
  return object < 0 ? paramKindName(kind) : fmt::format("{}[{}]", paramKindName(kind), object);
}

std::vector<ParamGroup> paramGroups(Appearance& a, Gradients* g, const ParamDomain& domain) {
  const size_t n = static_cast<size_t>(a.objectCount());
  auto floats = [](auto& v) {
    return std::span<float>(reinterpret_cast<float*>(v.data()), v.size() * sizeof(v[0]) / sizeof(float));
  };
  auto slice = [&](size_t begin, size_t count) {
    return g ? std::span<float>(g->objects).subspan(begin, count) : std::span<float>();
  };
  std::vector<ParamGroup> groups;
  groups.push_back(
      {ParamKind::Albedo, -1, 3, 0.0f, 1.0f, floats(a.albedo.rgb), g ? floats(g->albedo) : std::span<float>()});
  groups.push_back({ParamKind::Roughness, -1, 1, domain.roughnessMin, 1.0f, floats(a.roughness), slice(0, n)});
  groups.push_back({ParamKind::Specular, -1, 1, 0.0f, 1.0f, floats(a.specular), slice(n, n)});
  groups.push_back({ParamKind::Emission, -1, 3, 0.0f, kMaxEmission, floats(a.emission), slice(2 * n, 3 * n)});
  for (int o = 0; o < a.objectCount(); ++o)
    if (const int t = a.emissionTextureOf[o]; t >= 0)
      groups.push_back({ParamKind::EmissionTexture, o, 3, 0.0f, kMaxEmission, floats(a.emissionTextures[t].rgb),
                        g ? floats(g->emissionTexture[t]) : std::span<float>()});
  return groups;
}

float& paramValue(Appearance& a, const ParamRef& p) {
  for (ParamGroup& g : paramGroups(a))
    if (g.holds(p) && g.indexOf(p) < g.values.size()) return g.values[g.indexOf(p)];
  fail("{}: no such parameter in this scene", p.label());
}

float paramValue(const Appearance& a, const ParamRef& p) { return paramValue(const_cast<Appearance&>(a), p); }

float gradientValue(const Appearance& a, Gradients& grads, const ParamRef& p) {
  for (ParamGroup& g : paramGroups(const_cast<Appearance&>(a), &grads))
    if (g.holds(p) && g.indexOf(p) < g.grads.size()) return g.grads[g.indexOf(p)];
  fail("{}: no such parameter in this scene", p.label());
}

void projectToDomain(Appearance& a, const ParamDomain& domain) {
  for (ParamGroup& g : paramGroups(a, nullptr, domain))
    for (float& v : g.values) v = std::clamp(v, g.lo, g.hi);
}

void allocateEmissionTextures(Appearance& a, const TriangleMesh& mesh, int resolution,
                              const std::function<float(float, float)>& pattern) {
  if (!mesh.hasUv()) fail("emission textures need a uv atlas");
  std::vector<Eigen::AlignedBox2f> boxes(a.objectCount());
  for (size_t f = 0; f < mesh.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) boxes[mesh.faceObject[f]].extend(mesh.uvs[mesh.triangles[f][k]]);
  a.emissionTextures.clear();
  std::fill(a.emissionTextureOf.begin(), a.emissionTextureOf.end(), -1);
  for (int o = 0; o < a.objectCount(); ++o) {
    if (!a.isEmissive(o) || boxes[o].isEmpty()) continue;
    // One texel of margin so bilinear lookups at chart borders stay inside the window.
    const int x0 = std::max(0, static_cast<int>(std::floor(boxes[o].min().x() * resolution)) - 1);
    const int y0 = std::max(0, static_cast<int>(std::floor(boxes[o].min().y() * resolution)) - 1);
    const int x1 = std::min(resolution, static_cast<int>(std::ceil(boxes[o].max().x() * resolution)) + 1);
    const int y1 = std::min(resolution, static_cast<int>(std::ceil(boxes[o].max().y() * resolution)) + 1);
    Texture t(resolution, resolution, x0, y0, x1 - x0, y1 - y0);
    for (int y = 0; y < t.height; ++y)
      for (int x = 0; x < t.width; ++x) {
        const float u = (x + 0.5f) / t.width, v = (y + 0.5f) / t.height;
        const Color c = a.emission[o] * pattern(u, v);
        for (int c3 = 0; c3 < 3; ++c3) t.rgb[3 * (static_cast<size_t>(y) * t.width + x) + c3] = c[c3];
      }
    a.emissionTextureOf[o] = static_cast<int>(a.emissionTextures.size());
    a.emissionTextures.push_back(std::move(t));
  }
}

}  // namespace relume
