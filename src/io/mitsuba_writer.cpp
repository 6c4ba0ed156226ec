#include <string>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/export_scene.h"

namespace relume {
namespace {

std::string xmlEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string rgb(const char* name, const Color& c) {
  return fmt::format("<rgb name=\"{}\" value=\"{:.9g}, {:.9g}, {:.9g}\"/>", name, c[0], c[1], c[2]);
}

// Linear EXR, read raw and looked up bilinearly like relume's textures (wrap clamped); declared
// once at the top and referenced by id, so Mitsuba loads each atlas once.
std::string bitmap(const char* id, const std::string& file) {
  return fmt::format(
      "  <texture type=\"bitmap\" id=\"{}\">\n    <string name=\"filename\" value=\"{}\"/>\n"
      "    <string name=\"filter_type\" value=\"bilinear\"/>\n    <string name=\"wrap_mode\" value=\"clamp\"/>\n"
      "    <boolean name=\"raw\" value=\"true\"/>\n  </texture>\n",
      id, file);
}

std::string ref(const char* name, const char* id) { return fmt::format("<ref name=\"{}\" id=\"{}\"/>", name, id); }

// Mitsuba's principled BSDF (metallic 0, spec_tint 0) has relume's F0 = 0.08 specular and the
// exact dielectric Fresnel (F90 = 1); it is one-sided, relume shades both sides.
std::string shape(const ExportMaterial& m, const std::string& meshFile) {
  std::string s = fmt::format("  <shape type=\"ply\" id=\"{}\">\n    <string name=\"filename\" value=\"{}\"/>\n",
                              xmlEscape(m.name), meshFile);
  s += "    <bsdf type=\"twosided\">\n      <bsdf type=\"principled\">\n        ";
  s += m.baseColorTextured ? ref("base_color", "albedo") : rgb("base_color", m.baseColor);
  s += fmt::format(
      "\n        <float name=\"roughness\" value=\"{:.9g}\"/>\n        <float name=\"specular\" value=\"{:.9g}\"/>\n"
      "        <float name=\"metallic\" value=\"0\"/>\n        <float name=\"spec_tint\" value=\"0\"/>\n"
      "      </bsdf>\n    </bsdf>\n",
      m.roughness, m.specular);
  if (m.emissionTextured || m.emission.maxCoeff() > 0.0f)
    s += "    <emitter type=\"area\">" +
         (m.emissionTextured ? ref("radiance", "emission") : rgb("radiance", m.emission)) + "</emitter>\n";
  return s + "  </shape>\n";
}

}  // namespace

void writeMitsubaScene(const std::filesystem::path& dir, const ExportScene& scene, int maxDepth) {
  std::string xml =
      "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n<!-- written by relume; units: metres, linear Rec.709 -->\n";
  xml += "<scene version=\"3.0.0\">\n";
  // No Russian roulette: relume's default path has none either.
  xml += fmt::format(
      "  <integrator type=\"path\">\n    <integer name=\"max_depth\" value=\"{}\"/>\n"
      "    <integer name=\"rr_depth\" value=\"{}\"/>\n  </integrator>\n",
      maxDepth + 1, maxDepth + 2);
  if (!scene.albedo.rgb.empty()) xml += bitmap("albedo", "textures/albedo.exr");
  if (!scene.emission.rgb.empty()) xml += bitmap("emission", "textures/emission.exr");
  const std::vector<MeshData> submeshes = objectSubmeshes(scene.mesh, static_cast<int>(scene.materials.size()));
  for (size_t o = 0; o < scene.materials.size(); ++o) {
    const ExportMaterial& m = scene.materials[o];
    if ((m.baseColorTextured && scene.albedo.rgb.empty()) || (m.emissionTextured && scene.emission.rgb.empty()))
      fail("{}: material '{}' is textured but the scene has no texture", dir.string(), m.name);
    const MeshData& sub = submeshes[o];
    if (sub.triangles.empty()) continue;
    const std::string meshFile = fmt::format("meshes/object_{}.ply", o);
    writePly(dir / meshFile, sub);
    xml += shape(m, meshFile);
  }
  xml += "</scene>\n";
  if (!scene.albedo.rgb.empty()) writeExr(dir / "textures" / "albedo.exr", scene.albedo);
  if (!scene.emission.rgb.empty()) writeExr(dir / "textures" / "emission.exr", scene.emission);
  writeTextAtomically(dir / "scene.xml", xml);
}

}  // namespace relume
