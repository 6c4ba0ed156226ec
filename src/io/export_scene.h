// A reconstructed scene as the exporters see it: plain data, no renderer types. One material per
// object (segment); textures are atlas-sized and addressed by the mesh's uv (glTF convention:
// uv (0,0) is the top-left corner, row 0 the top).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "io/image.h"
#include "io/mesh_data.h"

namespace relume {

// Opaque dielectric, metallic 0: base colour (albedo), GGX with alpha = roughness^2, and a
// Fresnel with F0 = 0.08 * specular at normal incidence and f90 at grazing.
struct ExportMaterial {
  std::string name;
  Color baseColor = Color::Constant(0.5f);  // linear; ignored where baseColorTextured
  bool baseColorTextured = false;           // base colour = ExportScene::albedo at the uv
  float roughness = 0.5f;                   // perceptual
  float specular = 0.5f;                    // F0 = 0.08 * specular
  float f90 = 1.0f;                         // 1: exact dielectric Fresnel (principled-v1); specular: glTF's Schlick
  Color emission = Color::Zero();           // radiance (front side); ignored where emissionTextured
  bool emissionTextured = false;            // radiance = ExportScene::emission at the uv
};

struct ExportScene {
  MeshData mesh;                          // faceObject indexes materials (empty: all object 0)
  std::vector<ExportMaterial> materials;  // one per object id
  Image albedo;                           // linear, [0,1]; empty when no material is textured
  Image emission;                         // linear radiance; empty when no emitter is textured
};

// Per object id in [0, objects): its triangles with their vertices renumbered from 0, uv kept,
// normals kept when every one is usable; no face object ids. One pass over the mesh.
std::vector<MeshData> objectSubmeshes(const MeshData& mesh, int objects);

// glTF 2.0 binary (.glb), one node + mesh + material per object, textures embedded as sRGB PNG:
// KHR_materials_specular (F0 = min(0.04 specularColorFactor, 1) specularFactor, F90 =
// specularFactor) and KHR_materials_emissive_strength carry relume's F0/F90 and radiance above 1
// (docs/user/export.md). Atomic.
void writeGlb(const std::filesystem::path& path, const ExportScene& scene);

// Mitsuba 3 scene: DIR/scene.xml, one PLY per object under DIR/meshes, linear EXR textures under
// DIR/textures; principled BSDF (two-sided) per object and an area emitter per light source.
// `maxDepth` is relume's scattering vertices per path (Mitsuba's max_depth = maxDepth + 1).
void writeMitsubaScene(const std::filesystem::path& dir, const ExportScene& scene, int maxDepth);

}  // namespace relume
