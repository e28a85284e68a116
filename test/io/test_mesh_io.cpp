// Mesh I/O: writeMesh/readMesh round trips for PLY, OBJ and STL (STL also checked by a tiny parser
// here), polygon fans, OBJ index forms, the shared meshes against meshes.json, and located errors.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "core/mesh_shapes.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "io_test_util.hpp"
#include "json_report.hpp"

namespace {

using duplexfit::analyzeTopology;
using duplexfit::InvalidArgument;
using duplexfit::IoError;
using duplexfit::Mesh;
using duplexfit::MeshFormat;
using duplexfit::MeshTopology;
using duplexfit::readMesh;
using duplexfit::writeMesh;
using duplexfit::testing::checkIoError;
using duplexfit::testing::GenElement;
using duplexfit::testing::makePly;
using duplexfit::testing::readBytes;
using duplexfit::testing::TempDir;
using duplexfit::testing::writeBytes;

/// An octahedron whose coordinates are not floats (1/3 steps), shifted off the origin.
Mesh testMesh() {
  Mesh m = duplexfit::testing::octahedron(1.0 / 3.0);
  m.vertices.rowwise() += Eigen::RowVector3d(0.1, -0.7, 2.0);
  return m;
}

/// Faces equal up to a rotation of each triangle's corners.
bool sameTriangle(const Mesh& a, Eigen::Index fa, const Mesh& b, Eigen::Index fb) {
  for (int shift = 0; shift < 3; ++shift) {
    bool all = true;
    for (int k = 0; k < 3; ++k) {
      const Eigen::RowVector3d pa = a.vertices.row(a.faces(fa, k));
      const Eigen::RowVector3d pb = b.vertices.row(b.faces(fb, (k + shift) % 3));
      all = all && (pa - pb).norm() == 0.0;
    }
    if (all) return true;
  }
  return false;
}

/// A mesh whose vertices are `m`'s rounded to float.
Mesh roundedToFloat(const Mesh& m) {
  Mesh r = m;
  r.vertices = m.vertices.cast<float>().cast<double>();
  return r;
}

/// Minimal binary STL decoding: per-triangle normal and corners.
struct StlTriangle {
  float normal[3];
  float corners[9];
};
std::vector<StlTriangle> parseStl(const std::string& bytes) {
  REQUIRE(bytes.size() >= 84);
  std::uint32_t count = 0;
  std::memcpy(&count, bytes.data() + 80, 4);
  REQUIRE(bytes.size() == 84 + 50 * std::size_t{count});
  std::vector<StlTriangle> out(count);
  for (std::size_t t = 0; t < count; ++t) {
    std::memcpy(out[t].normal, bytes.data() + 84 + 50 * t, 12);
    std::memcpy(out[t].corners, bytes.data() + 84 + 50 * t + 12, 36);
  }
  return out;
}

}  // namespace

TEST_SUITE("io") {

TEST_CASE("mesh io: PLY round trip (float vertices, exact faces)") {
  TempDir dir;
  const Mesh m = testMesh();
  for (const char* name : {"m.ply", "m.PLY", "noextension"}) {
    CAPTURE(name);
    const std::string path = dir.file(name);
    writeMesh(path, m);
    const std::string bytes = readBytes(path);
    CHECK(bytes.find("format binary_little_endian 1.0\n") != std::string::npos);
    CHECK(bytes.find("element face 8\nproperty list uchar int vertex_indices\nend_header\n") !=
          std::string::npos);
    const Mesh back = readMesh(path);
    CHECK(back.vertices == roundedToFloat(m).vertices);
    CHECK(back.faces == m.faces);
  }
  CHECK(dir.entries().size() == 3);
}

TEST_CASE("mesh io: OBJ round trip is exact in double") {
  TempDir dir;
  const Mesh m = testMesh();
  for (const char* name : {"m.obj", "m.OBJ"}) {
    const std::string path = dir.file(name);
    writeMesh(path, m);
    const Mesh back = readMesh(path);
    CHECK(back.vertices == m.vertices);
    CHECK(back.faces == m.faces);
  }
  // An explicit format overrides the extension.
  const std::string other = dir.file("mesh.dat");
  writeMesh(other, m, MeshFormat::Obj);
  CHECK(readBytes(other).find("\nf 1 3 5\n") != std::string::npos);
  CHECK(readMesh(other, MeshFormat::Obj).vertices == m.vertices);
}

TEST_CASE("mesh io: binary STL has per-face normals and reads back welded") {
  TempDir dir;
  const Mesh m = testMesh();
  const std::string path = dir.file("m.Stl");
  writeMesh(path, m);
  const std::string bytes = readBytes(path);
  CHECK(bytes.compare(0, 5, "solid") != 0);
  const std::vector<StlTriangle> triangles = parseStl(bytes);
  REQUIRE(triangles.size() == 8);
  for (Eigen::Index f = 0; f < 8; ++f) {
    const StlTriangle& t = triangles[static_cast<std::size_t>(f)];
    const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)).transpose();
    const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1)).transpose();
    const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2)).transpose();
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    for (int k = 0; k < 3; ++k) {
      CHECK(static_cast<double>(t.normal[k]) == doctest::Approx(n(k)).epsilon(1e-6));
      CHECK(t.corners[k] == static_cast<float>(a(k)));
      CHECK(t.corners[3 + k] == static_cast<float>(b(k)));
      CHECK(t.corners[6 + k] == static_cast<float>(c(k)));
    }
  }
  const Mesh back = readMesh(path);
  CHECK(back.vertices.rows() == 6);
  REQUIRE(back.faces.rows() == 8);
  const Mesh rounded = roundedToFloat(m);
  for (Eigen::Index f = 0; f < 8; ++f) CHECK(sameTriangle(rounded, f, back, f));
  const MeshTopology t = analyzeTopology(back);
  CHECK(t.watertight());
  CHECK(t.oriented());
  CHECK(t.eulerCharacteristic == 2);

  // Ascii STL with a quad facet (fanned) and coordinates in exponent notation.
  const std::string ascii = dir.file("a.stl");
  writeBytes(ascii,
             "solid test\n"
             " facet normal 0 0 1\n  outer loop\n"
             "   vertex 0 0 0\n   vertex 1e0 0 0\n   vertex 1 1 0\n   vertex 0 1 0\n"
             "  endloop\n endfacet\n"
             " facet normal 0 0 1\n  outer loop\n"
             "   vertex 0 0 0\n   vertex 0 1 0\n   vertex -1 0 0\n"
             "  endloop\n endfacet\n"
             "endsolid test\n");
  const Mesh quad = readMesh(ascii);
  CHECK(quad.vertices.rows() == 5);
  CHECK(quad.faces.rows() == 3);
  CHECK(analyzeTopology(quad).boundaryEdges == 5);
}

TEST_CASE("mesh io: writeMesh rejects bad input and leaves no file") {
  TempDir dir;
  const Mesh m = testMesh();
  CHECK_THROWS_AS(writeMesh(dir.file("m.off"), m), InvalidArgument);
  CHECK_THROWS_AS(readMesh(dir.file("m.off")), InvalidArgument);
  Mesh bad = testMesh();
  bad.faces(6, 1) = 17;
  for (const char* name : {"bad.ply", "bad.obj", "bad.stl"}) {
    try {
      writeMesh(dir.file(name), bad);
      FAIL("no exception");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("face 6") != std::string::npos);
    }
  }
  Mesh withNan = m;
  withNan.vertices(4, 2) = std::nan("");
  CHECK_THROWS_WITH_AS(writeMesh(dir.file("nan.obj"), withNan), doctest::Contains("vertex 4"),
                       InvalidArgument);
  Mesh huge = m;
  huge.vertices(2, 0) = 1e300;
  CHECK_THROWS_AS(writeMesh(dir.file("huge.ply"), huge), InvalidArgument);
  CHECK_NOTHROW(writeMesh(dir.file("huge.obj"), huge));  // OBJ text holds any double
  CHECK(dir.entries() == std::vector<std::string>{"huge.obj"});

  // Replacing an existing file leaves only the new content.
  const std::string path = dir.file("huge.obj");
  writeMesh(path, m);
  CHECK(readMesh(path).vertices == m.vertices);
  CHECK(dir.entries() == std::vector<std::string>{"huge.obj"});
  const std::string missing = dir.file("no/such/folder/m.ply");
  checkIoError([&] { writeMesh(missing, m); }, missing, {"does not exist"});
}

TEST_CASE("mesh io: PLY faces of any integer type, polygons fanned, elements in any order") {
  TempDir dir;
  GenElement vertex;
  vertex.name = "vertex";
  vertex.properties = {{"double", "x", ""}, {"double", "y", ""}, {"double", "z", ""},
                       {"float", "nx", ""}, {"uchar", "red", ""}};
  const double corners[6][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {2, 2, 2}};
  for (const auto& c : corners) vertex.rows.push_back({{c[0]}, {c[1]}, {c[2]}, {0.5}, {9}});
  struct Variant {
    const char* countType;
    const char* itemType;
    const char* name;
  };
  const Variant variants[] = {{"uchar", "int", "vertex_indices"},
                              {"uchar", "uint", "vertex_index"},
                              {"int", "uchar", "vertex_indices"},
                              {"uint", "ushort", "vertex_indices"},
                              {"ushort", "int8", "corners"}};
  for (const char* encoding : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    for (const Variant& v : variants) {
      CAPTURE(encoding);
      CAPTURE(v.itemType);
      GenElement face;
      face.name = "face";
      face.properties = {{"uchar", "flags", ""}, {v.itemType, v.name, v.countType}};
      face.rows = {{{1}, {0, 1, 2, 3}}, {{2}, {0, 1, 4}}, {{3}, {1, 2, 5, 4, 0}}};
      for (const bool faceFirst : {false, true}) {
        const std::string path = dir.file("poly.ply");
        writeBytes(path, faceFirst ? makePly(encoding, {face, vertex})
                                   : makePly(encoding, {vertex, face}));
        const Mesh m = readMesh(path);
        CHECK(m.vertices.rows() == 6);
        CHECK(m.vertices(5, 1) == 2.0);
        REQUIRE(m.faces.rows() == 6);  // 2 + 1 + 3 triangles
        CHECK(m.faces.row(0) == Eigen::RowVector3i(0, 1, 2));
        CHECK(m.faces.row(1) == Eigen::RowVector3i(0, 2, 3));
        CHECK(m.faces.row(2) == Eigen::RowVector3i(0, 1, 4));
        CHECK(m.faces.row(5) == Eigen::RowVector3i(1, 4, 0));
      }
    }
  }
}

TEST_CASE("mesh io: OBJ vertex reference forms, negative indices and polygons") {
  TempDir dir;
  const std::string path = dir.file("forms.obj");
  writeBytes(path,
             "# comment\nmtllib x.mtl\no thing\n"
             "v 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\n"
             "vt 0 0\nvt 1 0\nvn 0 0 1\ng group\ns off\nusemtl m\n"
             "f 1 2 3\n"
             "f 1/1 3/2 4/1\n"
             "f 1/1/1 2/2/1 3/1/1\n"
             "f 1//1 3//1 4//1\r\n"
             "f -4 -3 -2 -1\n"
             "l 1 2\n"
             "v 0 0 1\n"
             "f -1 1 2   # a trailing comment\n");
  const Mesh m = readMesh(path);
  CHECK(m.vertices.rows() == 5);
  REQUIRE(m.faces.rows() == 7);
  CHECK(m.faces.row(0) == Eigen::RowVector3i(0, 1, 2));
  CHECK(m.faces.row(1) == Eigen::RowVector3i(0, 2, 3));
  CHECK(m.faces.row(2) == Eigen::RowVector3i(0, 1, 2));
  CHECK(m.faces.row(3) == Eigen::RowVector3i(0, 2, 3));
  CHECK(m.faces.row(4) == Eigen::RowVector3i(0, 1, 2));
  CHECK(m.faces.row(5) == Eigen::RowVector3i(0, 2, 3));
  CHECK(m.faces.row(6) == Eigen::RowVector3i(4, 0, 1));
}

TEST_CASE("mesh io: malformed mesh files are IoErrors naming face, vertex or line") {
  TempDir dir;
  auto check = [&](const std::string& name, const std::string& content,
                   std::initializer_list<const char*> parts) {
    const std::string path = dir.file(name);
    writeBytes(path, content);
    checkIoError([&] { (void)readMesh(path); }, path, parts);
  };
  GenElement vertex;
  vertex.name = "vertex";
  vertex.properties = {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}};
  vertex.rows = {{{0}, {0}, {0}}, {{1}, {0}, {0}}, {{0}, {1}, {0}}};
  GenElement face;
  face.name = "face";
  face.properties = {{"int", "vertex_indices", "uchar"}};
  face.rows = {{{0, 1, 2}}, {{0, 2, 3}}};
  for (const char* encoding : {"ascii", "binary_little_endian"}) {
    CAPTURE(encoding);
    const bool ascii = encoding[0] == 'a';
    check("range.ply", makePly(encoding, {vertex, face}),
          {"vertex index 3", "out of range [0, 3)",
           ascii ? "face 1 at line 15" : "face 1 at byte"});
    GenElement small = face;
    small.rows = {{{0, 1, 2}}, {{0, 2}}};
    check("two.ply", makePly(encoding, {vertex, small}), {"fewer than 3", "face 1"});
    GenElement nan = vertex;
    nan.rows[2][1] = {std::nan("")};
    check("nan.ply", makePly(encoding, {nan, face}), {"non-finite", "vertex 2"});
    check("noface.ply", makePly(encoding, {vertex}), {"no 'face' element"});
    const std::string good = makePly(encoding, {vertex, small});
    check("cut.ply", good.substr(0, good.size() - 2),
          {ascii ? "too few values for face 1" : "truncated binary body"});
    if (ascii) {
      check("early.ply", good.substr(0, good.rfind("2 0 2\n")), {"ends early at line 15"});
    }
  }
  check("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n\nf 1 3 4\n",
        {"face 1 at line 6", "refers to vertex 4", "3 vertices are defined"});
  check("negative.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", {"face 0 at line 4"});
  check("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", {"invalid vertex reference '0'"});
  check("junk.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x/2 3\n", {"invalid vertex reference 'x/2'"});
  check("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n", {"fewer than 3", "line 3"});
  check("nan.obj", "v 0 0 0\nv 1 nan 0\n", {"non-finite", "vertex 1 at line 2"});
  check("text.obj", "v 0 0 0\nv 1 q 0\n", {"non-numeric value 'q'", "line 2"});
  check("short.obj", "v 0 0\n", {"fewer than 3 coordinates", "line 1"});
  check("none.obj", "# only a comment\n", {"no vertices"});
  std::string stl(84, '\0');
  stl[80] = 2;
  check("short.stl", stl, {"size mismatch", "2 triangles", "184 bytes", "84 bytes"});
  check("tiny.stl", "abc", {"too short"});
  check("ascii.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 zz\n",
        {"non-numeric value 'zz'", "line 4"});
  check("open.stl", "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", {"ends inside"});
  check("word.stl", "solid x\nhello\n", {"unexpected 'hello'", "line 2"});
}

TEST_CASE("mesh io: the shared meshes read with the topology of meshes.json") {
  DUPLEXFIT_SHARED_DATA_DIR(data);
  using duplexfit::testing::Json;
  const Json json = duplexfit::testing::readJsonFile(data + "/meshes/meshes.json");
  // meshes.json is a list of {"file": "...", "vertices": V, "faces": F, ...} objects.
  REQUIRE(json.is_array());
  int checked = 0;
  for (const Json& entry : json) {
    auto number = [&](const char* key) {
      const double v = duplexfit::testing::jsonNumber(entry, std::string("/") + key);
      INFO("key " << key);
      REQUIRE_FALSE(std::isnan(v));
      return v;
    };
    const Json name = duplexfit::testing::jsonAt(entry, "/file");
    REQUIRE(name.is_string());
    const std::string file = name.get<std::string>();
    const double faces = number("faces");
#ifndef NDEBUG
    if (faces > 100000) {  // unoptimised (sanitizer) builds: skip the largest scan to stay fast
      DUPLEXFIT_SKIP_PART("the meshes of more than 100000 faces, in an unoptimised build");
      ++checked;
      continue;
    }
#endif
    CAPTURE(file);
    const Mesh m = readMesh(data + "/" + file);
    CHECK(static_cast<double>(m.vertices.rows()) == number("vertices"));
    CHECK(static_cast<double>(m.faces.rows()) == faces);
    const MeshTopology t = analyzeTopology(m);
    CHECK(static_cast<double>(t.eulerCharacteristic) == number("euler_characteristic"));
    CHECK(static_cast<double>(t.components) == number("components"));
    CHECK(t.watertight());
    CHECK(t.manifold());
    CHECK(t.oriented());
    CHECK(duplexfit::signedVolume(m) == doctest::Approx(number("volume")).epsilon(1e-6));
    CHECK(duplexfit::surfaceArea(m) == doctest::Approx(number("area")).epsilon(1e-6));
    ++checked;
  }
  CHECK(checked >= 10);

  // The two analytic meshes (not in meshes.json): [-0.5, 0.5]³ and the same minus one octant.
  for (const auto& [file, volume] : {std::pair<const char*, double>{"cube.ply", 1.0},
                                     std::pair<const char*, double>{"notched_cube.ply", 0.875}}) {
    CAPTURE(file);
    const Mesh m = readMesh(data + "/meshes/" + file);
    CHECK(m.vertices.rows() == 26);
    CHECK(m.faces.rows() == 48);
    const MeshTopology t = analyzeTopology(m);
    CHECK(t.eulerCharacteristic == 2);
    CHECK(t.components == 1);
    CHECK(t.watertight());
    CHECK(t.manifold());
    CHECK(t.oriented());
    CHECK(duplexfit::signedVolume(m) == doctest::Approx(volume).epsilon(1e-12));
    CHECK(duplexfit::surfaceArea(m) == doctest::Approx(6.0).epsilon(1e-12));
  }
}

TEST_CASE("mesh io: an OBJ polygon of 349k corners fans into linear memory") {
  // docs/reliability.md: the reported 0.7 MB file, one face cycling through 3 vertices.
  const TempDir dir;
  const std::string path = dir.file("polygon.obj");
  std::string text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf";
  const std::size_t corners = 349002;
  for (std::size_t i = 0; i < corners; ++i) {
    text += ' ';
    text += static_cast<char>('1' + i % 3);
  }
  text += '\n';
  writeBytes(path, text);
  const Mesh m = readMesh(path);
  REQUIRE(m.faces.rows() == static_cast<Eigen::Index>(corners - 2));
  CHECK(m.vertices.rows() == 3);
  CHECK(m.faces(0, 0) == 0);
  CHECK(m.faces(0, 1) == 1);
  CHECK(m.faces(0, 2) == 2);
  CHECK(m.faces.minCoeff() == 0);
  CHECK(m.faces.maxCoeff() == 2);
  // One corner more than the 1 MiB line limit allows is a located error, not an allocation.
  std::string tooLong = "f";
  while (tooLong.size() <= (std::size_t{1} << 20)) tooLong += " 1";
  writeBytes(path, "v 0 0 0\n" + tooLong + "\n");
  checkIoError([&] { readMesh(path); }, path, {"line 2", "longer than 1 MiB"});
}

TEST_CASE("mesh io: a part far from the origin is written in double PLY (float32 would merge its vertices)") {
  TempDir dir;
  Mesh m;
  m.vertices.resize(4, 3);
  m.vertices << 1e8, 1e8, 1e8, 1e8 + 0.5, 1e8, 1e8, 1e8, 1e8 + 0.5, 1e8, 1e8, 1e8, 1e8 + 0.5;
  m.faces.resize(4, 3);
  m.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  const std::string ply = (dir.path() / "far.ply").string();
  writeMesh(ply, m);
  CHECK(readBytes(ply).find("property double x") != std::string::npos);
  const Mesh back = readMesh(ply);
  CHECK((back.vertices - m.vertices).cwiseAbs().maxCoeff() == 0.0);
  CHECK_THROWS_WITH_AS(writeMesh((dir.path() / "far.stl").string(), m), doctest::Contains("float32 steps of 8"),
                       InvalidArgument);
  // Near the origin the same part stays float32.
  m.vertices.array() -= 1e8;
  writeMesh(ply, m);
  CHECK(readBytes(ply).find("property float x") != std::string::npos);
}

}  // TEST_SUITE
