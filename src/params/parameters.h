// The unknowns: albedo texels, per-object roughness / specular / emission, and emission texels of
// textured emitters. They live in an Appearance (what the renderer reads); this module adds
// addressing, domains, freezing, and gradient buffers that mirror them (gradients.h).
// `paramGroups` is the only place that enumerates the kinds of unknowns: projection, checkpoints,
// the optimiser, averaging and upsampling all go through the groups it returns.
#pragma once
#include <array>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "params/gradients.h"
#include "scene/appearance.h"

namespace relume {

enum class ParamKind { Albedo, Roughness, Specular, Emission, EmissionTexture };
inline constexpr std::array<ParamKind, 5> kAllParamKinds = {
    ParamKind::Albedo, ParamKind::Roughness, ParamKind::Specular, ParamKind::Emission, ParamKind::EmissionTexture};
const char* paramKindName(ParamKind kind);
ParamKind parseParamKind(const std::string& name);  // throws relume::Error

// Which kinds receive gradients (the rest are frozen).
struct ParamMask {
  unsigned bits = ~0u;
  bool active(ParamKind k) const { return bits >> static_cast<unsigned>(k) & 1u; }
  void set(ParamKind k, bool on) {
    bits = on ? bits | (1u << static_cast<unsigned>(k)) : bits & ~(1u << static_cast<unsigned>(k));
  }
  static ParamMask only(std::initializer_list<ParamKind> kinds) {
    ParamMask m{0};
    for (ParamKind k : kinds) m.set(k, true);
    return m;
  }
};

// One scalar unknown. `texel` indexes texture groups; `object` per-object groups and the emitter
// of an emission texture; `channel` RGB quantities.
struct ParamRef {
  ParamKind kind;
  int object = 0;
  uint32_t texel = 0;
  int channel = 0;
  std::string label() const;
};

struct ParamDomain {
  float roughnessMin = kRoughnessMin;
};

// A group of unknowns of one kind as flat floats, with its gradient buffer when one is given.
struct ParamGroup {
  ParamKind kind;
  int object = -1;   // the emitter of an emission-texture group; -1: one entry per object
  int channels = 1;  // floats per entry (3: RGB)
  float lo = 0.0f, hi = 1.0f;
  std::span<float> values;
  std::span<float> grads;  // empty without a Gradients
  bool textured() const { return kind == ParamKind::Albedo || kind == ParamKind::EmissionTexture; }
  std::string name() const;  // "albedo", "roughness", "emission_tex[4]"
  size_t indexOf(const ParamRef& p) const {
    return (textured() ? p.texel : static_cast<size_t>(p.object)) * channels + p.channel;
  }
  bool holds(const ParamRef& p) const { return p.kind == kind && (object < 0 || p.object == object); }
};

std::vector<ParamGroup> paramGroups(Appearance& a, Gradients* grads = nullptr, const ParamDomain& domain = {});

float& paramValue(Appearance& a, const ParamRef& p);
float paramValue(const Appearance& a, const ParamRef& p);

// Clamps every parameter into its domain: albedo [0,1], roughness [r_min,1], specular [0,1], emission >= 0.
void projectToDomain(Appearance& a, const ParamDomain& domain = {});

// The gradient of one unknown (a's layout addresses it).
float gradientValue(const Appearance& a, Gradients& g, const ParamRef& p);

// Gives every emitter object (isEmissive) an emission texture over the bounding window of its
// charts at `resolution`, initialised to its constant emission times `pattern(u, v)` (1 = flat).
// Non-emitters get none: only what the scene needs is allocated. Requires a uv mesh.
void allocateEmissionTextures(Appearance& a, const TriangleMesh& mesh, int resolution,
                              const std::function<float(float, float)>& pattern);

}  // namespace relume
