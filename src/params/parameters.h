// The unknowns: albedo texels, per-object roughness / specular / emission, and emission texels of
// textured emitters. They live in an Appearance (what the renderer reads); this module adds
// addressing, domain projection, freezing, and race-free gradient buffers that mirror them.
#pragma once
#include <tbb/enumerable_thread_specific.h>

#include <array>
#include <functional>
#include <atomic>
#include <string>
#include <vector>

#include "scene/appearance.h"

namespace relume {

enum class ParamKind { Albedo, Roughness, Specular, Emission, EmissionTexture };
inline constexpr std::array<ParamKind, 5> kAllParamKinds = {ParamKind::Albedo, ParamKind::Roughness, ParamKind::Specular,
                                                            ParamKind::Emission, ParamKind::EmissionTexture};
const char* paramKindName(ParamKind kind);
ParamKind parseParamKind(const std::string& name);  // throws relume::Error

// One scalar unknown. `index` is the texel (textures) or unused; `channel` for RGB quantities.
struct ParamRef {
  ParamKind kind;
  int object = 0;
  uint32_t texel = 0;
  int channel = 0;
  std::string label() const;
};

float& paramValue(Appearance& a, const ParamRef& p);
float paramValue(const Appearance& a, const ParamRef& p);

struct ParamDomain {
  float roughnessMin = kRoughnessMin;
};
// Clamps every parameter into its domain: albedo [0,1], roughness [r_min,1], specular [0,1], emission >= 0.
void projectToDomain(Appearance& a, const ParamDomain& domain = {});

// Gradient buffers. Texture scatters use relaxed atomic adds (contention is negligible over
// millions of texels); per-object scalars accumulate per thread in double and are combined
// after the pass, so millions of float additions lose nothing.
class Gradients {
 public:
  explicit Gradients(const Appearance& shape);
  void clear();
  void addAlbedo(uint32_t texel, const Color& g) {
    for (int c = 0; c < 3; ++c) std::atomic_ref<float>(albedo[3 * texel + c]).fetch_add(g[c], std::memory_order_relaxed);
  }
  void addEmissionTexel(int textureIndex, uint32_t texel, const Color& g) {
    float* d = emissionTexture[textureIndex].data() + 3 * texel;
    for (int c = 0; c < 3; ++c) std::atomic_ref<float>(d[c]).fetch_add(g[c], std::memory_order_relaxed);
  }
  // Thread-local accumulators for per-object scalars: [roughness | specular | emission rgb].
  std::vector<double>& objectLocal() { return objectLocal_.local(); }
  size_t roughnessSlot(int o) const { return static_cast<size_t>(o); }
  size_t specularSlot(int o) const { return static_cast<size_t>(objectCount_ + o); }
  size_t emissionSlot(int o, int c) const { return static_cast<size_t>(2 * objectCount_ + 3 * o + c); }
  // Folds the thread-local accumulators into `objects` (call once after each pass).
  void combine();
  double value(const ParamRef& p) const;

  std::vector<float> albedo;                      // texels * 3
  std::vector<std::vector<float>> emissionTexture;
  std::vector<double> objects;                    // combined [roughness | specular | emission rgb]

 private:
  int objectCount_;
  std::vector<int> emissionTextureOf_;
  tbb::enumerable_thread_specific<std::vector<double>> objectLocal_;
};

}  // namespace relume

namespace relume {
// Gives every emitter object (isEmissive) an emission texture over the bounding window of its
// charts at `resolution`, initialised to its constant emission times `pattern(u, v)` (1 = flat).
// Non-emitters get none: only what the scene needs is allocated. Requires a uv mesh.
void allocateEmissionTextures(Appearance& a, const TriangleMesh& mesh, int resolution,
                              const std::function<float(float, float)>& pattern);
}  // namespace relume
