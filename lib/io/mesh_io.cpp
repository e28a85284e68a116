// Mesh writers (binary PLY, OBJ, binary STL; all through AtomicFile) and readers (PLY in any
// encoding, OBJ, binary and ascii STL) with located error messages.
#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>
#include <cstring>
#include <limits>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>

#include "byte_reader.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "ply.hpp"
#include "io/mesh_3mf.hpp"

namespace duplexfit {

namespace {

MeshFormat resolveFormat(const std::string& path, MeshFormat format, const char* caller) {
  if (format != MeshFormat::Auto) return format;
  const MeshFormat byName = meshFormatOf(path);
  if (byName != MeshFormat::Auto) return byName;
  const std::string ext = io::lowerExtension(path);
  throw InvalidArgument(std::string(caller) + ": unknown mesh extension '" + ext + "' of " + path +
                        " (expected .ply, .obj, .stl or .3mf)");
}

/// Rejects what the formats cannot store: bad indices, non-finite or (for float formats) huge
/// values.
void validateForWriting(const std::string& path, const Mesh& mesh, bool floatFormat) {
  const Eigen::Index nv = mesh.vertices.rows();
  const double limit = floatFormat ? static_cast<double>(std::numeric_limits<float>::max())
                                   : std::numeric_limits<double>::max();
  for (Eigen::Index v = 0; v < nv; ++v) {
    if (!mesh.vertices.row(v).allFinite() || mesh.vertices.row(v).cwiseAbs().maxCoeff() > limit) {
      throw InvalidArgument(
          "writeMesh: vertex " + std::to_string(v) + " of " + path +
          (floatFormat ? " is not finite or does not fit in float" : " is not finite"));
    }
  }
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t i = mesh.faces(f, k);
      if (i < 0 || i >= nv) {
        throw InvalidArgument("writeMesh: face " + std::to_string(f) + " of " + path +
                              " has vertex index " + std::to_string(i) + " out of range [0, " +
                              std::to_string(nv) + ")");
      }
    }
  }
}

/// Appends `value` in little-endian byte order.
template <typename T>
void putLittle(std::vector<unsigned char>& out, T value) {
  unsigned char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if (!io::hostIsLittleEndian()) std::reverse(bytes, bytes + sizeof(T));
  out.insert(out.end(), bytes, bytes + sizeof(T));
}

/// Writes `block` when it has grown past 1 MiB (or always with `force`).
void drain(AtomicFile& file, std::vector<unsigned char>& block, bool force = false) {
  if (force || block.size() >= (std::size_t{1} << 20)) {
    file.write(block.data(), block.size());
    block.clear();
  }
}

/// The float32 spacing at the mesh's largest coordinate against its extent (a part 1 unit wide centred at
/// 1e8 has steps of 8). PLY switches to double below 10⁵ steps across the part (lossless, cheap); STL,
/// float32 only, is refused below 10³ steps, where the part itself is lost.
struct FloatResolution {
  double magnitude = 0.0, extent = 0.0, step = 0.0;
  bool enough() const { return !(step > 1e-5 * extent); }
  bool usable() const { return !(step > 1e-3 * extent); }
};

FloatResolution floatResolution(const Mesh& mesh) {
  FloatResolution r;
  if (mesh.vertices.rows() == 0) return r;
  const Eigen::RowVector3d lo = mesh.vertices.colwise().minCoeff(), hi = mesh.vertices.colwise().maxCoeff();
  r.magnitude = std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff());
  r.extent = (hi - lo).maxCoeff();
  // The spacing of float32 values at the magnitude: m = f · 2^e with f in [0.5, 1) has 24-bit steps 2^(e−24)
  // (1e8: 8; the earlier m · 2^−23 overstated it up to 2×).
  int exponent = 0;
  std::frexp(r.magnitude, &exponent);
  r.step = r.magnitude > 0.0 ? std::ldexp(1.0, exponent - 24) : 0.0;
  return r;
}

std::string describeResolution(const FloatResolution& r) {
  std::ostringstream s;
  s << "coordinates up to " << r.magnitude << " across an extent of " << r.extent << ": float32 steps of "
    << r.step;
  return s.str();
}

void writePly(const std::string& path, const Mesh& mesh) {
  // Double coordinates where float32 would merge the model's vertices (every PLY reader knows double).
  const bool wide = !floatResolution(mesh).enough();
  const char* type = wide ? "double" : "float";
  AtomicFile file(path);
  file.write(std::string("ply\nformat binary_little_endian 1.0\ncomment written by duplexfit\nelement vertex ") +
             std::to_string(mesh.vertices.rows()) + "\nproperty " + type + " x\nproperty " + type +
             " y\nproperty " + type + " z\nelement face " + std::to_string(mesh.faces.rows()) +
             "\nproperty list uchar int vertex_indices\nend_header\n");
  std::vector<unsigned char> block;
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    for (int k = 0; k < 3; ++k) {
      if (wide) {
        putLittle(block, mesh.vertices(v, k));
      } else {
        putLittle(block, static_cast<float>(mesh.vertices(v, k)));
      }
    }
    drain(file, block);
  }
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    block.push_back(3);
    for (int k = 0; k < 3; ++k) putLittle(block, mesh.faces(f, k));
    drain(file, block);
  }
  drain(file, block, true);
  file.commit();
}

void appendNumber(std::string& out, double value) {
  char text[32];
  const auto result = std::to_chars(text, text + sizeof text, value);  // shortest round trip
  out.append(text, result.ptr);
}

void writeObj(const std::string& path, const Mesh& mesh) {
  AtomicFile file(path);
  std::string text = "# written by duplexfit: " + std::to_string(mesh.vertices.rows()) +
                     " vertices, " + std::to_string(mesh.faces.rows()) + " triangles\n";
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    text += 'v';
    for (int k = 0; k < 3; ++k) {
      text += ' ';
      appendNumber(text, mesh.vertices(v, k));
    }
    text += '\n';
    if (text.size() >= (std::size_t{1} << 20)) {
      file.write(text);
      text.clear();
    }
  }
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    text += 'f';
    for (int k = 0; k < 3; ++k) {
      text += ' ';
      text += std::to_string(mesh.faces(f, k) + 1);
    }
    text += '\n';
    if (text.size() >= (std::size_t{1} << 20)) {
      file.write(text);
      text.clear();
    }
  }
  file.write(text);
  file.commit();
}

void writeStl(const std::string& path, const Mesh& mesh) {
  if (mesh.faces.rows() > std::numeric_limits<std::uint32_t>::max()) {
    throw InvalidArgument("writeMesh: too many faces for STL (" + path + ")");
  }
  const FloatResolution resolution = floatResolution(mesh);
  if (!resolution.usable()) {
    throw InvalidArgument("writeMesh: " + path + ": STL stores float32 only and the mesh has " +
                          describeResolution(resolution) + "; write PLY or OBJ (double), or move the part near the origin");
  }
  AtomicFile file(path);
  // The 80-byte header must not start with "solid", or readers take the file for ascii STL.
  std::string header = "binary STL written by duplexfit";
  header.resize(80, ' ');
  file.write(header);
  std::vector<unsigned char> block;
  putLittle(block, static_cast<std::uint32_t>(mesh.faces.rows()));
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const Eigen::Vector3d a = mesh.vertices.row(mesh.faces(f, 0)).transpose();
    const Eigen::Vector3d b = mesh.vertices.row(mesh.faces(f, 1)).transpose();
    const Eigen::Vector3d c = mesh.vertices.row(mesh.faces(f, 2)).transpose();
    Eigen::Vector3d normal = (b - a).cross(c - a);
    const double length = normal.norm();
    normal = length > 0.0 ? Eigen::Vector3d(normal / length) : Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) putLittle(block, static_cast<float>(normal(k)));
    for (const Eigen::Vector3d* p : {&a, &b, &c}) {
      for (int k = 0; k < 3; ++k) putLittle(block, static_cast<float>((*p)(k)));
    }
    putLittle(block, std::uint16_t{0});
    drain(file, block);
  }
  drain(file, block, true);
  file.commit();
}

/// Collects vertices and triangles; polygons are fanned from their first corner.
struct MeshBuilder {
  std::vector<double> vertices;
  std::vector<std::int32_t> faces;
  void fan(const std::vector<std::int32_t>& polygon) {
    for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
      faces.insert(faces.end(), {polygon[0], polygon[k], polygon[k + 1]});
    }
  }
  Mesh build() const {
    Mesh mesh;
    mesh.vertices.resize(static_cast<Eigen::Index>(vertices.size() / 3), 3);
    mesh.faces.resize(static_cast<Eigen::Index>(faces.size() / 3), 3);
    std::copy(vertices.begin(), vertices.end(), mesh.vertices.data());
    std::copy(faces.begin(), faces.end(), mesh.faces.data());
    return mesh;
  }
};

std::string describeValues(const double* v) {
  return "(" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) +
         ")";
}

Mesh readPlyMesh(const std::string& path) {
  io::PlyReader ply(path);
  const int vertexIndex = ply.findElement("vertex");
  if (vertexIndex < 0) ply.fail("the PLY header declares no 'vertex' element");
  const int faceIndex = ply.findElement("face");
  if (faceIndex < 0) {
    ply.fail("the PLY header declares no 'face' element (a point cloud? use readPointCloud)");
  }
  const io::PlyElement& vertex = ply.elements()[static_cast<std::size_t>(vertexIndex)];
  const io::PlyElement& face = ply.elements()[static_cast<std::size_t>(faceIndex)];
  if (vertex.count > std::numeric_limits<std::int32_t>::max()) {
    ply.fail("too many vertices for 32-bit face indices (" + std::to_string(vertex.count) + ")");
  }
  int columns[3];
  for (int k = 0; k < 3; ++k) {
    const char* name = k == 0 ? "x" : k == 1 ? "y" : "z";
    columns[k] = vertex.find(name);
    if (columns[k] < 0 || vertex.properties[static_cast<std::size_t>(columns[k])].list) {
      ply.fail(std::string("the vertex element has no scalar property '") + name + "'");
    }
  }
  int indices = face.find("vertex_indices");
  if (indices < 0) indices = face.find("vertex_index");
  if (indices < 0) {
    // Fall back to the only list property, whatever its name.
    for (std::size_t p = 0; p < face.properties.size(); ++p) {
      if (face.properties[p].list) indices = indices == -1 ? static_cast<int>(p) : -2;
    }
  }
  if (indices < 0 || !face.properties[static_cast<std::size_t>(indices)].list) {
    ply.fail("the face element has no list property 'vertex_indices'");
  }

  MeshBuilder builder;
  std::vector<double> values, list;
  std::vector<std::int32_t> polygon;
  const auto readVertices = [&] {
    ply.beginElement(static_cast<std::size_t>(vertexIndex));
    builder.vertices.reserve(static_cast<std::size_t>(
        3 * std::min<std::uint64_t>(static_cast<std::uint64_t>(vertex.count),
                                    ply.remainingBytes() / 3)));
    for (std::int64_t v = 0; v < vertex.count; ++v) {
      ply.readRow(values, -1, list);
      const double row[3] = {values[static_cast<std::size_t>(columns[0])],
                             values[static_cast<std::size_t>(columns[1])],
                             values[static_cast<std::size_t>(columns[2])]};
      if (!std::isfinite(row[0]) || !std::isfinite(row[1]) || !std::isfinite(row[2])) {
        ply.fail("non-finite coordinates " + describeValues(row) + " at " + ply.where());
      }
      builder.vertices.insert(builder.vertices.end(), row, row + 3);
    }
  };
  const auto readFaces = [&] {
    ply.beginElement(static_cast<std::size_t>(faceIndex));
    builder.faces.reserve(
        static_cast<std::size_t>(3 * std::min<std::uint64_t>(static_cast<std::uint64_t>(face.count),
                                                             ply.remainingBytes() / 4)));
    for (std::int64_t f = 0; f < face.count; ++f) {
      ply.readRow(values, indices, list);
      if (list.size() < 3) {
        ply.fail("fewer than 3 vertex indices (" + std::to_string(list.size()) + ") in " +
                 ply.where());
      }
      polygon.clear();
      for (const double index : list) {
        if (!(index >= 0.0 && index < static_cast<double>(vertex.count)) ||
            index != std::floor(index)) {
          ply.fail("vertex index " + std::to_string(index) + " out of range [0, " +
                   std::to_string(vertex.count) + ") in " + ply.where());
        }
        polygon.push_back(static_cast<std::int32_t>(index));
      }
      builder.fan(polygon);
    }
  };
  if (vertexIndex < faceIndex) {
    readVertices();
    readFaces();
  } else {
    readFaces();
    readVertices();
  }
  return builder.build();
}

Mesh readObjMesh(const std::string& path) {
  io::ByteReader reader(path);
  MeshBuilder builder;
  std::string line;
  std::vector<std::string_view> tokens;
  std::vector<std::int32_t> polygon;
  std::size_t faceCount = 0;
  for (;;) {
    const auto status = reader.readLine(line, std::size_t{1} << 20);
    if (status == io::ByteReader::LineStatus::EndOfFile) break;
    if (status == io::ByteReader::LineStatus::TooLong) {
      reader.fail("line " + std::to_string(reader.line() + 1) + " is longer than 1 MiB");
    }
    const std::string here = " at line " + std::to_string(reader.line());
    line.erase(std::min(line.find('#'), line.size()));
    io::splitWhitespace(line, tokens);
    if (tokens.empty()) continue;
    if (tokens[0] == "v") {
      const std::size_t vertex = builder.vertices.size() / 3;
      if (tokens.size() < 4) {
        reader.fail("vertex " + std::to_string(vertex) + here + " has fewer than 3 coordinates");
      }
      double row[3];
      for (int k = 0; k < 3; ++k) {
        if (!io::parseNumber(tokens[static_cast<std::size_t>(k) + 1], row[k])) {
          reader.fail("non-numeric value " + io::quoted(tokens[static_cast<std::size_t>(k) + 1]) +
                      " in vertex " + std::to_string(vertex) + here);
        }
      }
      if (!std::isfinite(row[0]) || !std::isfinite(row[1]) || !std::isfinite(row[2])) {
        reader.fail("non-finite coordinates " + describeValues(row) + " in vertex " +
                    std::to_string(vertex) + here);
      }
      if (vertex >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
        reader.fail("too many vertices for 32-bit face indices" + here);
      }
      builder.vertices.insert(builder.vertices.end(), row, row + 3);
    } else if (tokens[0] == "f") {
      const auto defined = static_cast<std::int64_t>(builder.vertices.size() / 3);
      const std::string which = "face " + std::to_string(faceCount) + here;
      if (tokens.size() < 4) reader.fail(which + " has fewer than 3 vertices");
      polygon.clear();
      for (std::size_t t = 1; t < tokens.size(); ++t) {
        const std::string_view ref = tokens[t].substr(0, tokens[t].find('/'));
        std::int64_t index = 0;
        const char* last = ref.data() + ref.size();
        const auto [ptr, ec] = std::from_chars(ref.data(), last, index);
        if (ec != std::errc() || ptr != last || index == 0) {
          reader.fail(which + ": invalid vertex reference " + io::quoted(tokens[t]));
        }
        const std::int64_t resolved = index > 0 ? index - 1 : defined + index;
        if (resolved < 0 || resolved >= defined) {
          reader.fail(which + " refers to vertex " + std::to_string(index) + ", but " +
                      std::to_string(defined) + " vertices are defined before it");
        }
        polygon.push_back(static_cast<std::int32_t>(resolved));
      }
      builder.fan(polygon);
      ++faceCount;
    }
    // Everything else (vt, vn, g, o, s, usemtl, mtllib, l, p, ...) carries nothing we need.
  }
  if (builder.vertices.empty()) reader.fail("no vertices ('v' lines): not an OBJ mesh?");
  return builder.build();
}

/// Welds STL corners with bit-identical coordinates into shared vertices.
class Welder {
 public:
  explicit Welder(MeshBuilder& builder) : builder_(builder) {}
  std::int32_t add(const double* p) {
    Key key{};
    for (int k = 0; k < 3; ++k) {
      const double v = p[k] == 0.0 ? 0.0 : p[k];  // −0 and +0 are one position
      std::memcpy(&key.bits[k], &v, sizeof v);
    }
    const auto next = static_cast<std::int32_t>(builder_.vertices.size() / 3);
    const auto [it, inserted] = map_.emplace(key, next);
    if (inserted) builder_.vertices.insert(builder_.vertices.end(), p, p + 3);
    return it->second;
  }

 private:
  struct Key {
    std::uint64_t bits[3];
    bool operator==(const Key& o) const {
      return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
    }
  };
  struct Hash {
    std::size_t operator()(const Key& k) const {
      std::uint64_t h = 1469598103934665603ULL;
      for (const std::uint64_t b : k.bits) h = (h ^ b) * 1099511628211ULL ^ (h >> 29);
      return static_cast<std::size_t>(h);
    }
  };
  MeshBuilder& builder_;
  std::unordered_map<Key, std::int32_t, Hash> map_;
};

Mesh readAsciiStl(const std::string& path) {
  io::ByteReader reader(path);
  MeshBuilder builder;
  Welder welder(builder);
  std::string line;
  std::vector<std::string_view> tokens;
  std::vector<std::int32_t> polygon;
  std::size_t facet = 0;
  bool inFacet = false;
  for (;;) {
    const auto status = reader.readLine(line, std::size_t{1} << 16);
    if (status == io::ByteReader::LineStatus::EndOfFile) break;
    if (status == io::ByteReader::LineStatus::TooLong) {
      reader.fail("line " + std::to_string(reader.line() + 1) + " is longer than 64 KiB");
    }
    const std::string here = " at line " + std::to_string(reader.line());
    io::splitWhitespace(line, tokens);
    if (tokens.empty()) continue;
    const std::string_view key = tokens[0];
    if (key == "facet") {
      if (inFacet) reader.fail("facet " + std::to_string(facet) + " has no endfacet" + here);
      inFacet = true;
      polygon.clear();
    } else if (key == "vertex") {
      if (!inFacet) reader.fail("vertex outside a facet" + here);
      double p[3];
      if (tokens.size() != 4) reader.fail("vertex line needs 3 coordinates" + here);
      for (int k = 0; k < 3; ++k) {
        if (!io::parseNumber(tokens[static_cast<std::size_t>(k) + 1], p[k])) {
          reader.fail("non-numeric value " + io::quoted(tokens[static_cast<std::size_t>(k) + 1]) +
                      " in facet " + std::to_string(facet) + here);
        }
      }
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
        reader.fail("non-finite vertex " + describeValues(p) + " in facet " +
                    std::to_string(facet) + here);
      }
      polygon.push_back(welder.add(p));
    } else if (key == "endfacet") {
      if (!inFacet) reader.fail("endfacet without facet" + here);
      if (polygon.size() < 3) {
        reader.fail("facet " + std::to_string(facet) + " has fewer than 3 vertices" + here);
      }
      builder.fan(polygon);
      inFacet = false;
      ++facet;
    } else if (key != "solid" && key != "endsolid" && key != "outer" && key != "endloop") {
      reader.fail("unexpected " + io::quoted(key) + here + " in ascii STL");
    }
  }
  if (inFacet) reader.fail("the file ends inside facet " + std::to_string(facet));
  return builder.build();
}

Mesh readStlMesh(const std::string& path) {
  io::ByteReader reader(path);
  unsigned char head[84];
  const std::size_t got = reader.read(head, sizeof head);
  std::uint32_t count = 0;
  if (got == sizeof head) {
    unsigned char c[4] = {head[80], head[81], head[82], head[83]};
    if (!io::hostIsLittleEndian()) std::reverse(c, c + 4);
    std::memcpy(&count, c, 4);
  }
  const bool sizeMatches = got == sizeof head && 84 + 50 * std::uint64_t{count} == reader.size();
  std::string start(reinterpret_cast<const char*>(head), got);
  start.erase(0, std::min(start.find_first_not_of(" \t\r\n"), start.size()));
  if (!sizeMatches && start.compare(0, 5, "solid") == 0) return readAsciiStl(path);
  if (got < sizeof head) {
    reader.fail("too short for a binary STL (" + std::to_string(got) +
                " bytes, the header alone is 84)");
  }
  if (!sizeMatches) {
    reader.fail("binary STL size mismatch: the header declares " + std::to_string(count) +
                " triangles (" + std::to_string(84 + 50 * std::uint64_t{count}) +
                " bytes) but the file has " + std::to_string(reader.size()) + " bytes");
  }
  MeshBuilder builder;
  Welder welder(builder);
  builder.faces.reserve(3 * std::size_t{count});
  unsigned char record[50];
  std::vector<std::int32_t> polygon(3);
  for (std::uint32_t t = 0; t < count; ++t) {
    const std::uint64_t offset = reader.offset();
    if (reader.read(record, sizeof record) != sizeof record) {
      reader.fail("truncated binary STL in triangle " + std::to_string(t));
    }
    for (int corner = 0; corner < 3; ++corner) {
      double p[3];
      for (int k = 0; k < 3; ++k) {
        unsigned char* b = record + 12 + 12 * corner + 4 * k;
        if (!io::hostIsLittleEndian()) std::reverse(b, b + 4);
        float value = 0.0f;
        std::memcpy(&value, b, 4);
        p[k] = static_cast<double>(value);
      }
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
        reader.fail("non-finite vertex " + describeValues(p) + " in triangle " + std::to_string(t) +
                    " at byte offset " + std::to_string(offset));
      }
      polygon[static_cast<std::size_t>(corner)] = welder.add(p);
    }
    builder.fan(polygon);
  }
  return builder.build();
}

}  // namespace

bool mesh3mfAvailable() noexcept { return io::threeMfAvailable(); }

const char* meshFormatName(MeshFormat format) noexcept {
  switch (format) {
    case MeshFormat::Auto:
      return "auto";
    case MeshFormat::Ply:
      return "ply";
    case MeshFormat::Obj:
      return "obj";
    case MeshFormat::Stl:
      return "stl";
    case MeshFormat::ThreeMf:
      return "3mf";
  }
  return "?";
}

MeshFormat meshFormatOf(const std::string& path) {
  const std::string ext = io::lowerExtension(path);
  if (ext.empty() || ext == ".ply") return MeshFormat::Ply;
  if (ext == ".obj") return MeshFormat::Obj;
  if (ext == ".stl") return MeshFormat::Stl;
  if (ext == ".3mf") return MeshFormat::ThreeMf;
  return MeshFormat::Auto;
}

const char* inputKindName(InputKind kind) noexcept {
  switch (kind) {
    case InputKind::Auto:
      return "auto";
    case InputKind::Cloud:
      return "cloud";
    case InputKind::Mesh:
      return "mesh";
  }
  return "?";
}

InputKind detectInputKind(const std::string& path) {
  const std::string ext = io::lowerExtension(path);
  if (ext == ".stl" || ext == ".obj" || ext == ".3mf") return InputKind::Mesh;
  if (ext != ".ply") return InputKind::Cloud;
  const io::PlyReader ply(path);  // the header only
  const int face = ply.findElement("face");
  return face >= 0 && ply.elements()[static_cast<std::size_t>(face)].count > 0 ? InputKind::Mesh : InputKind::Cloud;
}

void writeMesh(const std::string& path, const Mesh& mesh, MeshFormat format) {
  const MeshFormat resolved = resolveFormat(path, format, "writeMesh");
  validateForWriting(path, mesh, resolved != MeshFormat::Obj);
  switch (resolved) {
    case MeshFormat::Obj:
      writeObj(path, mesh);
      return;
    case MeshFormat::Stl:
      writeStl(path, mesh);
      return;
    case MeshFormat::ThreeMf:
      io::write3mf(path, mesh);
      return;
    case MeshFormat::Ply:
    case MeshFormat::Auto:
      break;
  }
  writePly(path, mesh);
}

Mesh readMesh(const std::string& path, MeshFormat format) {
  switch (resolveFormat(path, format, "readMesh")) {
    case MeshFormat::Obj:
      return readObjMesh(path);
    case MeshFormat::Stl:
      return readStlMesh(path);
    case MeshFormat::ThreeMf:
      return io::read3mf(path);
    case MeshFormat::Ply:
    case MeshFormat::Auto:
      break;
  }
  return readPlyMesh(path);
}

}  // namespace duplexfit
