// Point cloud I/O: PLY round trips for every encoding and scalar type, both normal namings, skipped
// extra properties and elements, XYZ text, the shared clouds against their manifest, located
// errors for malformed input, and truncation/mutation fuzzing that may only ever raise IoError.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "io_test_util.hpp"
#include "json_report.hpp"

namespace {

using duplexfit::InvalidArgument;
using duplexfit::IoError;
using duplexfit::PlyEncoding;
using duplexfit::PointCloudFile;
using duplexfit::PointFormat;
using duplexfit::PointReadOptions;
using duplexfit::Points;
using duplexfit::PointSet;
using duplexfit::readPointCloud;
using duplexfit::readPointCloudWithReport;
using duplexfit::testing::checkIoError;
using duplexfit::testing::GenElement;
using duplexfit::testing::makePly;
using duplexfit::testing::readBytes;
using duplexfit::testing::TempDir;
using duplexfit::testing::vertexElement;
using duplexfit::testing::writeBytes;

const char* const kEncodings[] = {"ascii", "binary_little_endian", "binary_big_endian"};

/// 12 points as x y z nx ny nz, representable in every PLY type (signed types get negative y,
/// float types a fraction).
std::vector<double> samplePoints(bool isSigned, bool isFloat) {
  std::vector<double> v;
  for (int i = 0; i < 12; ++i) {
    const double frac = isFloat ? 0.25 : 0.0;
    v.insert(v.end(), {7.0 * i + frac, (isSigned ? -1.0 : 1.0) * (3.0 * i + 1.0),
                       100.0 - 5.0 * i - frac});
    if (i % 2 == 0) {
      v.insert(v.end(), {3.0, 4.0, 0.0});
    } else {
      v.insert(v.end(), {0.0, 0.0, 2.0});
    }
  }
  return v;
}

/// Checks a read cloud against samplePoints' values (positions exact, normals normalised).
void checkSample(const PointSet& cloud, const std::vector<double>& expected) {
  REQUIRE(cloud.size() == expected.size() / 6);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const auto r = static_cast<Eigen::Index>(i);
    for (int k = 0; k < 3; ++k) CHECK(cloud.positions()(r, k) == expected[6 * i + std::size_t(k)]);
    Eigen::Vector3d n(expected[6 * i + 3], expected[6 * i + 4], expected[6 * i + 5]);
    n.normalize();
    for (int k = 0; k < 3; ++k) {
      CHECK(cloud.normals()(r, k) == doctest::Approx(n(k)).epsilon(1e-15));
    }
  }
}

/// A valid ascii cloud of three points whose rows are lines 12, 13 and 14.
std::string asciiCloud() {
  return makePly("ascii", {vertexElement("float", {0, 0, 0, 0, 0, 1,  //
                                                   1, 0, 0, 0, 0, 1,  //
                                                   0, 1, 0, 0, 0, 1})});
}

std::string replaceOnce(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

/// Reads a file with every reader entry point; only IoError may escape.
void readAnyway(const std::string& path) {
  for (const PointFormat format : {PointFormat::Ply, PointFormat::Xyz}) {
    PointReadOptions options;
    options.format = format;
    options.requireNormals = format == PointFormat::Ply;
    try {
      (void)readPointCloud(path, options);
    } catch (const IoError&) {
    }
  }
  for (const auto format :
       {duplexfit::MeshFormat::Ply, duplexfit::MeshFormat::Obj, duplexfit::MeshFormat::Stl}) {
    try {
      (void)duplexfit::readMesh(path, format);
    } catch (const IoError&) {
    }
  }
}

}  // namespace

TEST_SUITE("io") {

TEST_CASE("point io: PLY round trip for every encoding and scalar type") {
  TempDir dir;
  const char* const types[] = {"char",  "uchar", "short",   "ushort",  "int",    "uint",
                               "float", "double", "int8",   "uint8",   "int16",  "uint16",
                               "int32", "uint32", "float32", "float64"};
  for (const char* encoding : kEncodings) {
    for (const char* type : types) {
      CAPTURE(encoding);
      CAPTURE(type);
      const std::string t = type;
      const bool isFloat = t.find("float") == 0 || t == "double";
      const bool isSigned = isFloat || t[0] != 'u';
      const std::vector<double> values = samplePoints(isSigned, isFloat);
      const std::string path = dir.file(std::string(encoding) + "_" + type + ".ply");
      writeBytes(path, makePly(encoding, {vertexElement(type, values)}));
      const PointCloudFile read = readPointCloudWithReport(path);
      checkSample(read.points, values);
      CHECK(read.report.format == PointFormat::Ply);
      CHECK(std::string(duplexfit::plyEncodingName(read.report.encoding)) == encoding);
      CHECK(read.report.points == 12);
      CHECK(read.report.normals);
      CHECK(read.report.properties == std::vector<std::string>{"x", "y", "z", "nx", "ny", "nz"});
    }
  }
}

TEST_CASE("point io: normals named normal_x/normal_y/normal_z") {
  TempDir dir;
  const std::vector<double> values = samplePoints(true, true);
  for (const char* encoding : kEncodings) {
    CAPTURE(encoding);
    const std::string path = dir.file(std::string(encoding) + ".ply");
    writeBytes(path, makePly(encoding, {vertexElement("double", values, "normal_x", "normal_y",
                                                      "normal_z")}));
    const PointCloudFile read = readPointCloudWithReport(path);
    checkSample(read.points, values);
    CHECK(read.report.normals);
  }
}

TEST_CASE("point io: extra vertex properties, lists and other elements are skipped") {
  TempDir dir;
  const std::vector<double> values = samplePoints(true, true);
  GenElement material;  // before the vertices: must be skipped, lists included
  material.name = "material";
  material.properties = {{"uchar", "red", ""}, {"int", "ids", "uchar"}, {"float", "shine", ""}};
  material.rows = {{{255}, {1, 2, 3}, {0.5}}, {{7}, {}, {1.5}}};
  GenElement vertex;
  vertex.name = "vertex";
  vertex.properties = {{"float", "x", ""},       {"uchar", "red", ""},
                       {"float", "y", ""},       {"int", "vertex_indices", "uchar"},
                       {"double", "z", ""},      {"float", "nx", ""},
                       {"float", "ny", ""},      {"float", "nz", ""},
                       {"ushort", "quality", ""}, {"double", "weights", "uint"}};
  for (std::size_t i = 0; i < values.size() / 6; ++i) {
    std::vector<double> list(i % 4, static_cast<double>(i));
    vertex.rows.push_back({{values[6 * i]},
                           {static_cast<double>(i)},
                           {values[6 * i + 1]},
                           list,
                           {values[6 * i + 2]},
                           {values[6 * i + 3]},
                           {values[6 * i + 4]},
                           {values[6 * i + 5]},
                           {65535},
                           {0.25, -0.5}});
  }
  GenElement face;
  face.name = "face";
  face.properties = {{"int", "vertex_indices", "uchar"}, {"uint", "flags", ""}};
  face.rows = {{{0, 1, 2}, {9}}, {{2, 3, 4, 5}, {1}}};
  GenElement edge;
  edge.name = "edge";
  edge.properties = {{"int", "vertex1", ""}, {"int", "vertex2", ""}};
  edge.rows = {{{0}, {1}}, {{1}, {2}}};
  for (const char* encoding : kEncodings) {
    CAPTURE(encoding);
    const std::string path = dir.file(std::string(encoding) + ".ply");
    writeBytes(path, makePly(encoding, {material, vertex, face, edge},
                             "obj_info made for a test\ncomment second comment\n"));
    const PointCloudFile read = readPointCloudWithReport(path);
    checkSample(read.points, values);
    CHECK(read.report.properties.size() == 10);
    CHECK(read.report.properties[3] == "vertex_indices");
    REQUIRE(read.report.comments.size() == 3);
    CHECK(read.report.comments[1] == "made for a test");
    CHECK(read.report.comments[2] == "second comment");
  }
}

TEST_CASE("point io: CRLF header lines and blank lines in an ascii body are accepted") {
  TempDir dir;
  std::string text = asciiCloud();
  std::string crlf;
  for (const char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  crlf = replaceOnce(crlf, "end_header\r\n", "end_header\r\n\r\n");
  const std::string path = dir.file("crlf.ply");
  writeBytes(path, crlf);
  const PointSet cloud = readPointCloud(path);
  CHECK(cloud.size() == 3);
  CHECK(cloud.positions()(2, 1) == 1.0);
}

TEST_CASE("point io: readPlyVertexRows reads a row range of a binary PLY, the rows of the whole read") {
  TempDir dir;
  const int n = 20000;  // larger than the reader's buffer, so the skip seeks
  Points p(n, 3), q(n, 3);
  for (int i = 0; i < n; ++i) {
    p.row(i) << 0.001 * i, std::sin(0.01 * i), -0.5 + 1e-4 * i;
    q.row(i) << 1.0, 0.5 * (i % 3), -1.0;
  }
  const std::string path = dir.file("rows.ply");
  duplexfit::writePointCloud(path, PointSet(p, q));
  CHECK(duplexfit::plyVertexCount(path) == n);
  const PointSet whole = duplexfit::readPointCloud(path);
  for (const auto& [first, count] : std::vector<std::pair<int, int>>{{0, 7}, {13, 1000}, {15000, 5000}, {n, 0}, {9999, 1}}) {
    const duplexfit::PointCloudFile part = duplexfit::readPlyVertexRows(path, first, count);
    REQUIRE(part.points.size() == static_cast<std::size_t>(count));
    CHECK(part.report.points == static_cast<std::size_t>(count));
    for (int i = 0; i < count; ++i) {
      CHECK(part.points.positions().row(i) == whole.positions().row(first + i));
      CHECK(part.points.normals().row(i) == whole.normals().row(first + i));
    }
  }
  // A range outside the element is an IoError naming the file and the element's size.
  try {
    (void)duplexfit::readPlyVertexRows(path, 19990, 11);
    FAIL("no error");
  } catch (const duplexfit::IoError& e) {
    const std::string what = e.what();
    CHECK(what.find("rows.ply") != std::string::npos);
    CHECK(what.find("the vertex element has 20000 rows") != std::string::npos);
  }
  CHECK_THROWS_AS(duplexfit::readPlyVertexRows(path, 0, -1), duplexfit::InvalidArgument);
}

TEST_CASE("point io: writePointCloud writes the shared cloud layout and reads back") {
  TempDir dir;
  Points p(5, 3), n(5, 3);
  for (int i = 0; i < 5; ++i) {
    p.row(i) << 0.125 * i, -0.5 + 0.25 * i, 1.0 / (i + 1);
    n.row(i) << 0.0, (i % 2 != 0 ? 1.0 : -1.0), 0.0;
  }
  n.row(4).setZero();
  const PointSet cloud(p, n);
  const std::string path = dir.file("out.ply");
  duplexfit::writePointCloud(path, cloud);
  CHECK(dir.entries() == std::vector<std::string>{"out.ply"});
  const std::string bytes = readBytes(path);
  const std::size_t body = bytes.find("end_header\n") + 11;
  CHECK(bytes.size() == body + 24 * 5);
  CHECK(bytes.find("format binary_little_endian 1.0\n") != std::string::npos);
  CHECK(bytes.find("element vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                   "property float nx\nproperty float ny\nproperty float nz\nend_header\n") !=
        std::string::npos);
  const PointSet back = readPointCloud(path);
  REQUIRE(back.size() == 5);
  for (int i = 0; i < 5; ++i) {
    for (int k = 0; k < 3; ++k) {
      CHECK(back.positions()(i, k) == static_cast<double>(static_cast<float>(p(i, k))));
      CHECK(back.normals()(i, k) == cloud.normals()(i, k));
    }
  }
  CHECK(back.zeroNormals() == 1);

  Points huge = p;
  huge(2, 1) = 1e300;
  CHECK_THROWS_AS(duplexfit::writePointCloud(dir.file("huge.ply"), PointSet(huge, n)),
                  InvalidArgument);
  CHECK(dir.entries() == std::vector<std::string>{"out.ply"});
}

TEST_CASE("point io: XYZ text with comments, blank lines, commas and a format override") {
  TempDir dir;
  const std::string text =
      "# a comment line\n"
      "\n"
      "0 0 0 0 0 2   # trailing comment\n"
      "  1.5\t-2e-1 3 1 0 0\r\n"
      "1,2,3,0,1,0\n"
      "+4 5 6 0 0 -1\n";
  for (const char* name : {"a.xyz", "a.txt", "a.pts", "a.XYZ"}) {
    CAPTURE(name);
    const std::string path = dir.file(name);
    writeBytes(path, text);
    const PointCloudFile read = readPointCloudWithReport(path);
    REQUIRE(read.points.size() == 4);
    CHECK(read.report.format == PointFormat::Xyz);
    CHECK(read.report.normals);
    CHECK(read.points.positions()(1, 0) == 1.5);
    CHECK(read.points.positions()(1, 1) == -0.2);
    CHECK(read.points.positions()(2, 2) == 3.0);
    CHECK(read.points.positions()(3, 0) == 4.0);
    CHECK(read.points.normals()(0, 2) == 1.0);
  }
  const std::string counted = dir.file("counted.pts");
  writeBytes(counted, "2\n0 0 0 0 0 1\n1 1 1 0 1 0\n");
  CHECK(readPointCloud(counted).size() == 2);
  const std::string other = dir.file("points.dat");
  writeBytes(other, text);
  CHECK_THROWS_AS(readPointCloud(other), InvalidArgument);
  PointReadOptions options;
  options.format = PointFormat::Xyz;
  CHECK(readPointCloud(other, options).size() == 4);

  // A PLY under an .xyz name, read with an explicit format.
  const std::string plyAsXyz = dir.file("cloud.xyz");
  writeBytes(plyAsXyz, asciiCloud());
  options.format = PointFormat::Ply;
  CHECK(readPointCloud(plyAsXyz, options).size() == 3);
}

TEST_CASE("point io: files without normals read with zero normals only when allowed") {
  TempDir dir;
  const std::string xyz = dir.file("plain.xyz");
  writeBytes(xyz, "0 0 0\n1 0 0\n0 1 0\n");
  GenElement v;
  v.name = "vertex";
  v.properties = {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}};
  v.rows = {{{0}, {0}, {0}}, {{1}, {0}, {0}}};
  const std::string ply = dir.file("plain.ply");
  writeBytes(ply, makePly("binary_little_endian", {v}));

  checkIoError([&] { (void)readPointCloud(xyz); }, xyz, {"no normals", "line 1", "duplexfit normals"});
  checkIoError([&] { (void)readPointCloud(ply); }, ply,
               {"no normals", "nx ny nz", "vertex properties: x y z", "estimate and orient", "--estimate-normals"});
  PointReadOptions lenient;
  lenient.requireNormals = false;
  const PointCloudFile a = readPointCloudWithReport(xyz, lenient);
  CHECK(a.points.size() == 3);
  CHECK(a.points.zeroNormals() == 3);
  CHECK_FALSE(a.report.normals);
  const PointCloudFile b = readPointCloudWithReport(ply, lenient);
  CHECK(b.points.size() == 2);
  CHECK_FALSE(b.report.normals);
}

TEST_CASE("point io: the shared clouds read with the manifest's point counts") {
  DUPLEXFIT_SHARED_DATA_DIR(data);
  const duplexfit::testing::Json manifest = duplexfit::testing::readJsonFile(data + "/clouds/manifest.json");
  // The manifest lists {"file": "...", "points": N, ...} objects under "clouds".
  const duplexfit::testing::Json list = duplexfit::testing::jsonAt(manifest, "/clouds");
  REQUIRE(list.is_array());
  std::vector<std::pair<std::string, std::size_t>> clouds;
  for (const duplexfit::testing::Json& entry : list) {
    const duplexfit::testing::Json file = duplexfit::testing::jsonAt(entry, "/file");
    const duplexfit::testing::Json points = duplexfit::testing::jsonAt(entry, "/points");
    REQUIRE(file.is_string());
    REQUIRE(points.is_number_unsigned());
    clouds.emplace_back(file.get<std::string>(), points.get<std::size_t>());
  }
  CHECK(clouds.size() >= 20);
  for (const auto& [file, count] : clouds) {
    CAPTURE(file);
#ifndef NDEBUG
    if (count > 100000) {  // unoptimised (sanitizer) builds: skip the largest clouds
      DUPLEXFIT_SKIP_PART("the clouds of more than 100000 points, in an unoptimised build");
      continue;
    }
#endif
    const std::string path = data + "/" + file;
    const PointCloudFile read = readPointCloudWithReport(path);
    CHECK(read.points.size() == count);
    CHECK(read.report.encoding == PlyEncoding::BinaryLittleEndian);
    CHECK(read.report.normals);
    CHECK(read.points.zeroNormals() == 0);
    const Eigen::AlignedBox3d box = read.points.bounds();
    CHECK(box.max().maxCoeff() <= 0.55);  // unit frame; the noisy clouds stick out a little
    CHECK(box.min().minCoeff() >= -0.55);
    CHECK(std::filesystem::file_size(path) ==
          readBytes(path).find("end_header\n") + 11 + 24 * count);
  }
  // The smallest cloud against a direct decoding of its float32 body.
  const std::string sphere = data + "/clouds/sphere_180.ply";
  const std::string bytes = readBytes(sphere);
  const std::size_t body = bytes.find("end_header\n") + 11;
  const PointSet cloud = readPointCloud(sphere);
  REQUIRE(cloud.size() == 180);
  for (Eigen::Index i = 0; i < 180; ++i) {
    float row[6];
    std::memcpy(row, bytes.data() + body + 24 * static_cast<std::size_t>(i), sizeof row);
    for (int k = 0; k < 3; ++k) CHECK(cloud.positions()(i, k) == static_cast<double>(row[k]));
    CHECK(cloud.normals().row(i).norm() == doctest::Approx(1.0).epsilon(1e-12));
  }
}

TEST_CASE("point io: malformed PLY headers are IoErrors naming file and line") {
  TempDir dir;
  const std::string good = asciiCloud();
  auto check = [&](const std::string& name, const std::string& content,
                   std::initializer_list<const char*> parts) {
    const std::string path = dir.file(name);
    writeBytes(path, content);
    checkIoError([&] { (void)readPointCloud(path); }, path, parts);
  };
  const std::string missing = dir.file("missing.ply");
  checkIoError([&] { (void)readPointCloud(missing); }, missing, {"cannot open"});
  const std::string folder = dir.file("folder.ply");
  std::filesystem::create_directory(folder);
  checkIoError([&] { (void)readPointCloud(folder); }, folder, {"folder"});
  check("empty.ply", "", {"empty file"});
  check("magic.ply", "hello world\n1 2 3\n", {"not a PLY file"});
  check("binary.ply", std::string("\x89PNG\r\n\x1a\n", 8), {"not a PLY file"});
  check("noend.ply", "ply\nformat ascii 1.0\nelement vertex 0\n", {"end_header", "line 4"});
  check("format.ply", replaceOnce(good, "format ascii 1.0", "format binary_middle_endian 1.0"),
        {"unknown PLY format 'binary_middle_endian'", "line 2"});
  check("version.ply", replaceOnce(good, "format ascii 1.0", "format ascii 2.0"),
        {"version", "line 2"});
  check("noformat.ply", replaceOnce(good, "format ascii 1.0\n", ""), {"no format line"});
  check("type.ply", replaceOnce(good, "property float x", "property float16 x"),
        {"unknown property type 'float16'", "line 5"});
  check("listtype.ply", replaceOnce(good, "property float x", "property list float int x"),
        {"not an integer type", "line 5"});
  check("count.ply", replaceOnce(good, "element vertex 3", "element vertex -3"),
        {"invalid element count '-3'", "line 4"});
  check("keyword.ply", replaceOnce(good, "comment", "remark"), {"keyword 'remark'", "line 3"});
  check("orphan.ply", replaceOnce(good, "element vertex 3\n", ""), {"property before any element"});
  check("novertex.ply", replaceOnce(good, "element vertex", "element point"),
        {"no 'vertex' element"});
  check("nox.ply", replaceOnce(good, "property float x", "property float u"), {"no property 'x'"});
  check("partial.ply", replaceOnce(good, "property float nz", "property float w"),
        {"only some of the normal properties"});
  check("listx.ply", replaceOnce(good, "property float x", "property list uchar float x"),
        {"'x' is a list"});
}

TEST_CASE("point io: malformed ascii bodies are IoErrors naming vertex and line") {
  TempDir dir;
  const std::string good = asciiCloud();
  auto check = [&](const std::string& name, const std::string& content,
                   std::initializer_list<const char*> parts) {
    const std::string path = dir.file(name);
    writeBytes(path, content);
    checkIoError([&] { (void)readPointCloud(path); }, path, parts);
  };
  check("early.ply", replaceOnce(good, "element vertex 3", "element vertex 5"),
        {"ends early", "line 15", "5 vertex elements", "has 3"});
  check("extra.ply", replaceOnce(good, "1 0 0 0 0 1", "1 0 0 0 0 1 7"),
        {"extra values", "vertex 1 at line 13"});
  check("few.ply", replaceOnce(good, "1 0 0 0 0 1", "1 0 0 0 0"),
        {"too few values", "vertex 1 at line 13", "'nz'"});
  check("text.ply", replaceOnce(good, "1 0 0 0 0 1", "1 abc 0 0 0 1"),
        {"non-numeric value 'abc'", "'y'", "vertex 1 at line 13"});
  check("nan.ply", replaceOnce(good, "1 0 0 0 0 1", "1 nan 0 0 0 1"),
        {"non-finite coordinates", "vertex 1 at line 13"});
  check("inf.ply", replaceOnce(good, "0 1 0 0 0 1", "0 1 -inf 0 0 1"),
        {"non-finite coordinates", "vertex 2 at line 14"});
  check("nannormal.ply", replaceOnce(good, "0 1 0 0 0 1", "0 1 0 0 NaN 1"),
        {"non-finite normal", "vertex 2 at line 14"});
  check("overflow.ply", replaceOnce(good, "0 1 0 0 0 1", "0 1e999 0 0 0 1"),
        {"non-finite coordinates", "vertex 2 at line 14"});
}

TEST_CASE("point io: truncated and non-finite binary bodies name vertex and byte offset") {
  TempDir dir;
  const std::vector<double> values = samplePoints(true, true);
  for (const char* encoding : {"binary_little_endian", "binary_big_endian"}) {
    CAPTURE(encoding);
    const std::string good = makePly(encoding, {vertexElement("float", values)});
    const std::size_t header = good.find("end_header\n") + 11;
    const std::string cut = dir.file("cut.ply");
    writeBytes(cut, good.substr(0, good.size() - 10));
    checkIoError([&] { (void)readPointCloud(cut); }, cut,
                 {"truncated binary body", "12 vertex elements of 24 bytes",
                  ("byte offset " + std::to_string(header)).c_str(), "10 bytes missing",
                  "ends in vertex 11"});
    writeBytes(cut, good.substr(0, header));
    checkIoError([&] { (void)readPointCloud(cut); }, cut,
                 {"288 bytes missing", "ends in vertex 0"});

    std::string bad = good;
    bad.replace(header + 24 * 5 + 4, 4, "\xff\xff\xff\xff");  // vertex 5, y: NaN in either order
    const std::string path = dir.file("nan.ply");
    writeBytes(path, bad);
    checkIoError([&] { (void)readPointCloud(path); }, path,
                 {"non-finite coordinates",
                  ("vertex 5 at byte offset " + std::to_string(header + 24 * 5)).c_str()});
  }
  // Variable-size rows (a list on the vertices): the error names the row being read.
  GenElement v = vertexElement("float", values);
  v.properties.push_back({"int", "ids", "uchar"});
  for (auto& row : v.rows) row.push_back({1, 2});
  const std::string good = makePly("binary_little_endian", {v});
  const std::string cut = dir.file("list.ply");
  writeBytes(cut, good.substr(0, good.size() - 3));
  checkIoError([&] { (void)readPointCloud(cut); }, cut,
               {"truncated binary body", "in vertex 11 of 12"});
}

TEST_CASE("point io: malformed XYZ lines are IoErrors naming the line") {
  TempDir dir;
  auto check = [&](const std::string& content, std::initializer_list<const char*> parts) {
    const std::string path = dir.file("bad.xyz");
    writeBytes(path, content);
    checkIoError([&] { (void)readPointCloud(path); }, path, parts);
  };
  check("0 0 0 0 0 1\n# c\n1 x 0 0 0 1\n", {"non-numeric value 'x'", "line 3"});
  check("0 0 0 0 0 1\n\n\n1 0 0 0 0\n", {"expected 6 values", "found 5", "line 4"});
  check("0 0 0 0 0 1\nnan 0 0 0 0 1\n", {"non-finite coordinates", "line 2", "point 1"});
  check("0 0 0 0 0 1\n0 0 0 0 inf 1\n", {"non-finite normal", "line 2"});
  check("1 2 3 4\n", {"expected 6 values", "found 4", "line 1"});
  check("# nothing\n\n   \n", {"no points"});
  check(std::string("\0\0\0\0", 4), {"expected 6 values", "found 1", "line 1"});
  check("0 0 0 0 0 1\n1 2 3 \x01 5 6\n", {"non-numeric value '\\x01'", "line 2"});
}

TEST_CASE("point io: a file cut at every byte or mutated at random only raises IoError") {
  TempDir dir;
  const std::vector<double> values = samplePoints(true, true);
  GenElement face;
  face.name = "face";
  face.properties = {{"int", "vertex_indices", "uchar"}};
  face.rows = {{{0, 1, 2}}, {{2, 3, 4, 5}}};
  std::vector<std::string> files;
  for (const char* encoding : kEncodings) {
    GenElement v = vertexElement(encoding[0] == 'a' ? "float" : "double",
                                 std::vector<double>(values.begin(), values.begin() + 36));
    v.properties.push_back({"short", "ids", "uchar"});
    for (auto& row : v.rows) row.push_back({1, -2});
    files.push_back(makePly(encoding, {v, face}));
  }
  const std::string path = dir.file("fuzz.ply");
  for (const std::string& file : files) {
    for (std::size_t n = 0; n <= file.size(); ++n) {
      writeBytes(path, file.substr(0, n));
      readAnyway(path);
    }
  }
  std::mt19937 rng(20240611u);
  for (int round = 0; round < 3000; ++round) {
    std::string bytes = files[static_cast<std::size_t>(round) % files.size()];
    const int flips = 1 + round % 8;
    for (int f = 0; f < flips; ++f) {
      const std::size_t at = rng() % bytes.size();
      switch (rng() % 4) {
        case 0: bytes[at] = static_cast<char>(rng() & 0xff); break;
        case 1: bytes[at] = static_cast<char>("0123456789 \n-.e"[rng() % 15]); break;
        case 2: bytes.erase(at, 1 + rng() % 4); break;
        default: bytes.insert(at, 1 + rng() % 3, static_cast<char>(rng() & 0xff)); break;
      }
      if (bytes.empty()) bytes = "p";
    }
    writeBytes(path, bytes);
    readAnyway(path);
  }
  for (int round = 0; round < 1000; ++round) {
    std::string bytes = round % 2 == 0 ? "ply\n" : "";
    const std::size_t n = rng() % 300;
    for (std::size_t i = 0; i < n; ++i) bytes += static_cast<char>(rng() & 0xff);
    writeBytes(path, bytes);
    readAnyway(path);
  }
  // Huge declared counts must fail fast instead of allocating or looping.
  const std::string huge =
      "ply\nformat binary_little_endian 1.0\nelement vertex 9000000000000000000\n"
      "property float x\nproperty float y\nproperty float z\nproperty float nx\n"
      "property float ny\nproperty float nz\nend_header\n0123456789";
  writeBytes(path, huge);
  checkIoError([&] { (void)readPointCloud(path); }, path, {"truncated binary body"});
  std::string hugeList = replaceOnce(huge, "property float nz\n",
                                     "property float nz\nproperty list uint int ids\n");
  writeBytes(path, hugeList);
  checkIoError([&] { (void)readPointCloud(path); }, path, {"truncated binary body"});
}

}  // TEST_SUITE
