// PLY reader/writer. The reader trusts nothing in the header: every count is checked against the
// bytes actually present before anything is allocated, every index against the vertex count.
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>

#include "core/error.h"
#include "io/atomic_file.h"
#include "io/input_file.h"
#include "io/mesh_data.h"

namespace relume {
namespace {

enum class Format { Ascii, BinaryLE, BinaryBE };
enum class Type { I8, U8, I16, U16, I32, U32, F32, F64 };

std::optional<Type> parseType(const std::string& s) {
  if (s == "char" || s == "int8") return Type::I8;
  if (s == "uchar" || s == "uint8") return Type::U8;
  if (s == "short" || s == "int16") return Type::I16;
  if (s == "ushort" || s == "uint16") return Type::U16;
  if (s == "int" || s == "int32") return Type::I32;
  if (s == "uint" || s == "uint32") return Type::U32;
  if (s == "float" || s == "float32") return Type::F32;
  if (s == "double" || s == "float64") return Type::F64;
  return std::nullopt;
}

size_t typeSize(Type t) {
  switch (t) {
    case Type::I8:
    case Type::U8:
      return 1;
    case Type::I16:
    case Type::U16:
      return 2;
    case Type::I32:
    case Type::U32:
    case Type::F32:
      return 4;
    case Type::F64:
      return 8;
  }
  return 0;
}

struct Property {
  std::string name;
  Type type = Type::F32;
  bool isList = false;
  Type countType = Type::U8;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

// Reads values of either encoding from an in-memory body, with bounds checks.
class Cursor {
 public:
  Cursor(const std::string& file, const char* begin, const char* end, Format format)
      : file_(file), p_(begin), end_(end), format_(format) {}

  double read(Type t, const char* what) {
    if (format_ == Format::Ascii) return readAscii(what);
    const size_t n = typeSize(t);
    if (static_cast<size_t>(end_ - p_) < n) fail("{}: truncated binary data while reading {}", file_, what);
    unsigned char bytes[8];
    std::memcpy(bytes, p_, n);
    p_ += n;
    if ((format_ == Format::BinaryBE) == (std::endian::native == std::endian::little)) std::reverse(bytes, bytes + n);
    switch (t) {
      case Type::I8:
        return static_cast<int8_t>(bytes[0]);
      case Type::U8:
        return bytes[0];
      case Type::I16: {
        int16_t v;
        std::memcpy(&v, bytes, 2);
        return v;
      }
      case Type::U16: {
        uint16_t v;
        std::memcpy(&v, bytes, 2);
        return v;
      }
      case Type::I32: {
        int32_t v;
        std::memcpy(&v, bytes, 4);
        return v;
      }
      case Type::U32: {
        uint32_t v;
        std::memcpy(&v, bytes, 4);
        return v;
      }
      case Type::F32: {
        float v;
        std::memcpy(&v, bytes, 4);
        return v;
      }
      case Type::F64: {
        double v;
        std::memcpy(&v, bytes, 8);
        return v;
      }
    }
    return 0;
  }
  size_t remaining() const { return static_cast<size_t>(end_ - p_); }

 private:
  double readAscii(const char* what) {
    while (p_ < end_ && std::isspace(static_cast<unsigned char>(*p_))) ++p_;
    if (p_ >= end_) fail("{}: unexpected end of file while reading {}", file_, what);
    const char* tokenEnd = p_;
    while (tokenEnd < end_ && !std::isspace(static_cast<unsigned char>(*tokenEnd))) ++tokenEnd;
    double v = 0;
    const auto [ptr, ec] = std::from_chars(p_, tokenEnd, v);
    if (ec != std::errc() || ptr != tokenEnd)
      fail("{}: non-numeric token '{}' while reading {}", file_, std::string(p_, std::min<size_t>(tokenEnd - p_, 32)),
           what);
    p_ = tokenEnd;
    return v;
  }
  const std::string& file_;
  const char* p_;
  const char* end_;
  Format format_;
};

// A list length as read (any numeric type, ascii may even say "nan"): an integer in [0, 1e6].
size_t listLength(double n, const std::string& file, const std::string& what, uint64_t index) {
  if (!(n >= 0 && n <= 1e6) || n != std::floor(n)) fail("{}: {} {}: bad list length {}", file, what, index, n);
  return static_cast<size_t>(n);
}

int findProperty(const Element& e, std::initializer_list<const char*> names) {
  for (const char* n : names)
    for (size_t i = 0; i < e.properties.size(); ++i)
      if (!e.properties[i].isList && e.properties[i].name == n) return static_cast<int>(i);
  return -1;
}

// The parsed header: the body's encoding, its elements in file order, and where the body starts.
struct Header {
  Format format = Format::Ascii;
  std::vector<Element> elements;
  size_t bodyStart = 0;
};

// Finds the header's extent: checks the magic and the 'end_header' line, so the body's first byte
// is known before any line is read.
size_t findBodyStart(const std::string& data, const std::string& file, size_t& headerEnd) {
  headerEnd = data.find("end_header");
  if (data.rfind("ply", 0) != 0) fail("{}: not a PLY file (missing 'ply' magic)", file);
  if (headerEnd == std::string::npos) fail("{}: PLY header has no 'end_header'", file);
  size_t bodyStart = data.find('\n', headerEnd);
  if (bodyStart == std::string::npos) fail("{}: PLY header not terminated by a newline", file);
  return bodyStart + 1;
}

// One 'property' line (after the keyword): a scalar or a list, with known types and a name.
Property parseProperty(std::istringstream& ls, const std::string& line, const std::string& file, int lineNo) {
  Property p;
  std::string t;
  ls >> t;
  if (t == "list") {
    std::string ct, vt;
    ls >> ct >> vt >> p.name;
    const auto c = parseType(ct), v = parseType(vt);
    if (!c || !v || p.name.empty()) fail("{}: line {}: malformed list property '{}'", file, lineNo, line);
    p.isList = true;
    p.countType = *c;
    p.type = *v;
  } else {
    const auto v = parseType(t);
    ls >> p.name;
    if (!v || p.name.empty()) fail("{}: line {}: unknown property type in '{}'", file, lineNo, line);
    p.type = *v;
  }
  return p;
}

// Header parsing: the format line and the element and property declarations, line by line;
// anything else but comments is refused so a malformed file fails here, not in the body.
Header parseHeader(const std::string& data, const std::string& file) {
  size_t headerEnd = 0;
  Header h;
  h.bodyStart = findBodyStart(data, file, headerEnd);
  std::istringstream header(data.substr(0, headerEnd));
  std::string line;
  std::optional<Format> format;
  int lineNo = 0;
  while (std::getline(header, line)) {
    ++lineNo;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key.empty() || key == "ply" || key == "comment" || key == "obj_info") continue;
    if (key == "format") {
      std::string f;
      ls >> f;
      if (f == "ascii")
        format = Format::Ascii;
      else if (f == "binary_little_endian")
        format = Format::BinaryLE;
      else if (f == "binary_big_endian")
        format = Format::BinaryBE;
      else
        fail("{}: line {}: unknown PLY format '{}'", file, lineNo, f);
    } else if (key == "element") {
      Element e;
      std::string count;
      ls >> e.name >> count;
      const auto [ptr, ec] = std::from_chars(count.data(), count.data() + count.size(), e.count);
      if (e.name.empty() || ec != std::errc() || ptr != count.data() + count.size())
        fail("{}: line {}: malformed element declaration '{}'", file, lineNo, line);
      h.elements.push_back(e);
    } else if (key == "property") {
      if (h.elements.empty()) fail("{}: line {}: property before any element", file, lineNo);
      h.elements.back().properties.push_back(parseProperty(ls, line, file, lineNo));
    } else {
      fail("{}: line {}: unexpected header keyword '{}'", file, lineNo, key);
    }
  }
  if (!format) fail("{}: PLY header has no format line", file);
  h.format = *format;
  return h;
}

// Element layout check: each entry needs at least one byte per scalar (binary) or two chars
// (ascii), so absurd counts are refused before anything is reserved for them.
void checkElementFits(const Element& e, Format format, const Cursor& cur, const std::string& file) {
  size_t minBytes = 0;
  for (const Property& p : e.properties) minBytes += p.isList ? typeSize(p.countType) : typeSize(p.type);
  if (format == Format::Ascii) minBytes = 2 * e.properties.size();
  if (e.properties.empty() && e.count > 0)
    fail("{}: element '{}' declares {} entries but no properties", file, e.name, e.count);
  if (minBytes > 0 && e.count > cur.remaining() / minBytes)
    fail("{}: element '{}' declares {} entries but the file holds at most {}", file, e.name, e.count,
         cur.remaining() / minBytes);
}

// Where the vertex element keeps what relume reads: position (required), normal and uv (optional,
// under their common names); -1 where absent.
struct VertexLayout {
  int px, py, pz, nx, ny, nz, pu, pv;
  bool hasN, hasUv;
};

VertexLayout vertexLayout(const Element& e, const std::string& file) {
  VertexLayout l;
  l.px = findProperty(e, {"x"}), l.py = findProperty(e, {"y"}), l.pz = findProperty(e, {"z"});
  if (l.px < 0 || l.py < 0 || l.pz < 0) fail("{}: vertex element lacks x/y/z", file);
  l.nx = findProperty(e, {"nx"}), l.ny = findProperty(e, {"ny"}), l.nz = findProperty(e, {"nz"});
  l.pu = findProperty(e, {"s", "u", "texture_u"}), l.pv = findProperty(e, {"t", "v", "texture_v"});
  l.hasN = l.nx >= 0 && l.ny >= 0 && l.nz >= 0, l.hasUv = l.pu >= 0 && l.pv >= 0;
  return l;
}

// Vertex read: every property of every vertex is consumed (lists skipped) to stay in step with the
// body; positions must be finite.
void readVertices(const Element& e, Cursor& cur, const std::string& file, MeshData& mesh) {
  const VertexLayout l = vertexLayout(e, file);
  mesh.positions.resize(e.count);
  if (l.hasN) mesh.normals.resize(e.count);
  if (l.hasUv) mesh.uvs.resize(e.count);
  std::vector<double> vals(e.properties.size());
  for (uint64_t i = 0; i < e.count; ++i) {
    for (size_t k = 0; k < e.properties.size(); ++k) {
      const Property& p = e.properties[k];
      if (p.isList) {
        const size_t n = listLength(cur.read(p.countType, "vertex list count"), file, "vertex", i);
        for (size_t j = 0; j < n; ++j) cur.read(p.type, "vertex list item");
      } else {
        vals[k] = cur.read(p.type, "vertex property");
      }
    }
    mesh.positions[i] = Vec3(vals[l.px], vals[l.py], vals[l.pz]);
    if (!mesh.positions[i].allFinite()) fail("{}: vertex {} has a non-finite position", file, i);
    if (l.hasN) mesh.normals[i] = Vec3(vals[l.nx], vals[l.ny], vals[l.nz]);
    if (l.hasUv) mesh.uvs[i] = Vec2(vals[l.pu], vals[l.pv]);
  }
}

// Where the face element keeps its vertex index list (required) and its object label (optional,
// under the names scanners use); -1 where absent.
struct FaceLayout {
  int indices = -1, label = -1;
};

FaceLayout faceLayout(const Element& e, const std::string& file) {
  FaceLayout l;
  for (size_t k = 0; k < e.properties.size(); ++k)
    if (e.properties[k].isList && (e.properties[k].name == "vertex_indices" || e.properties[k].name == "vertex_index"))
      l.indices = static_cast<int>(k);
  if (l.indices < 0) fail("{}: face element lacks a vertex_indices list", file);
  l.label = findProperty(e, {"object_id", "segment_id", "label", "instance", "objectId"});
  return l;
}

// Face read: polygons fan-triangulated from their first corner, every index checked against the
// vertices read so far, labels checked to be small non-negative integers.
void readFaces(const Element& e, Cursor& cur, const std::string& file, MeshData& mesh) {
  const FaceLayout l = faceLayout(e, file);
  const int listIdx = l.indices, label = l.label;
  mesh.triangles.reserve(e.count);
  if (label >= 0) mesh.faceObject.reserve(e.count);
  std::vector<int64_t> poly;
  for (uint64_t i = 0; i < e.count; ++i) {
    double labelValue = 0;
    for (size_t k = 0; k < e.properties.size(); ++k) {
      const Property& p = e.properties[k];
      if (p.isList) {
        const size_t n = listLength(cur.read(p.countType, "face vertex count"), file, "face", i);
        if (static_cast<int>(k) == listIdx) poly.resize(n);
        for (size_t j = 0; j < n; ++j) {
          const double idx = cur.read(p.type, "face vertex index");
          if (static_cast<int>(k) != listIdx) continue;
          if (idx < 0 || idx >= static_cast<double>(mesh.positions.size()) || idx != std::floor(idx))
            fail("{}: face {}: vertex index {} out of range [0,{})", file, i, idx, mesh.positions.size());
          poly[j] = static_cast<int64_t>(idx);
        }
      } else {
        const double v = cur.read(p.type, "face property");
        if (static_cast<int>(k) == label) labelValue = v;
      }
    }
    if (poly.size() < 3) fail("{}: face {} has {} vertices (need >= 3)", file, i, poly.size());
    if (label >= 0 && (labelValue < 0 || labelValue > 1e7 || labelValue != std::floor(labelValue)))
      fail("{}: face {}: object id {} is not a non-negative integer", file, i, labelValue);
    if (poly.size() > 3) ++mesh.polygonsTriangulated;
    for (size_t j = 1; j + 1 < poly.size(); ++j) {
      mesh.triangles.emplace_back(poly[0], poly[j], poly[j + 1]);
      if (label >= 0) mesh.faceObject.push_back(static_cast<int32_t>(labelValue));
    }
  }
}

// Any other element is read and dropped, its list lengths still checked, to reach the next one.
void skipElement(const Element& e, Cursor& cur, const std::string& file) {
  for (uint64_t i = 0; i < e.count; ++i)
    for (const Property& p : e.properties) {
      const size_t n =
          p.isList ? listLength(cur.read(p.countType, "list count"), file, "element '" + e.name + "'", i) : 1;
      for (size_t j = 0; j < n; ++j) cur.read(p.type, e.name.c_str());
    }
}

// Validation: a mesh needs vertices and at least one face.
void checkMesh(const MeshData& mesh, bool haveVertices, const std::string& file) {
  if (!haveVertices) fail("{}: PLY has no vertex element", file);
  if (mesh.triangles.empty()) fail("{}: PLY has no faces", file);
}

}  // namespace

MeshData readPly(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string data = readRegularFile(path, "a PLY mesh");
  const Header h = parseHeader(data, file);
  Cursor cur(file, data.data() + h.bodyStart, data.data() + data.size(), h.format);
  MeshData mesh;
  bool haveVertices = false;
  for (const Element& e : h.elements) {
    checkElementFits(e, h.format, cur, file);
    if (e.name == "vertex") {
      haveVertices = true;
      readVertices(e, cur, file, mesh);
    } else if (e.name == "face") {
      if (!haveVertices) fail("{}: face element before vertex element", file);
      readFaces(e, cur, file, mesh);
    } else {
      skipElement(e, cur, file);
    }
  }
  checkMesh(mesh, haveVertices, file);
  return mesh;
}

void writePly(const std::filesystem::path& path, const MeshData& mesh) {
  std::string out;
  out += "ply\nformat binary_little_endian 1.0\ncomment written by relume\n";
  out +=
      fmt::format("element vertex {}\nproperty float x\nproperty float y\nproperty float z\n", mesh.positions.size());
  const bool hasN = mesh.normals.size() == mesh.positions.size() && !mesh.normals.empty();
  const bool hasUv = mesh.uvs.size() == mesh.positions.size() && !mesh.uvs.empty();
  const bool hasObj = mesh.faceObject.size() == mesh.triangles.size() && !mesh.faceObject.empty();
  if (hasN) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (hasUv) out += "property float s\nproperty float t\n";
  out += fmt::format("element face {}\nproperty list uchar int vertex_indices\n", mesh.triangles.size());
  if (hasObj) out += "property int object_id\n";
  out += "end_header\n";
  auto put = [&out](const auto& v) { out.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
  static_assert(std::endian::native == std::endian::little);
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    for (int k = 0; k < 3; ++k) put(mesh.positions[i][k]);
    if (hasN)
      for (int k = 0; k < 3; ++k) put(mesh.normals[i][k]);
    if (hasUv)
      for (int k = 0; k < 2; ++k) put(mesh.uvs[i][k]);
  }
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    put(static_cast<uint8_t>(3));
    for (int k = 0; k < 3; ++k) put(static_cast<int32_t>(mesh.triangles[i][k]));
    if (hasObj) put(mesh.faceObject[i]);
  }
  writeTextAtomically(path, out);
}

}  // namespace relume
