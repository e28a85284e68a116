// 3MF meshes (lib3mf, an optional build component): written as a 3MF package (a zip with the 3MF parts),
// read back with the same vertices (float32) and faces, deterministic bytes, clear errors; without lib3mf a
// clear error that says so.
#include <doctest/doctest.h>

#include <string>

#include "core/mesh_shapes.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh.hpp"
#include "io_test_util.hpp"
#include "skip.hpp"

namespace {

using namespace duplexfit;
using testing::readBytes;
using testing::TempDir;

}  // namespace

TEST_SUITE("io") {
  TEST_CASE("mesh io: 3MF round trip through lib3mf, deterministic, with the 3MF package parts") {
    if (!mesh3mfAvailable()) DUPLEXFIT_SKIP("this build has no lib3mf (Debian: lib3mf-dev)");
    TempDir dir;
    Mesh m = testing::octahedron(0.5);
    m.vertices.col(0).array() += 10.125;  // away from the origin: coordinates are written as they are
    const std::string path = dir.file("part.3mf");
    writeMesh(path, m);
    const std::string bytes = readBytes(path);
    REQUIRE(bytes.size() > 4);
    CHECK(bytes.compare(0, 4, std::string("PK\x03\x04", 4)) == 0);  // a zip (Open Packaging Conventions)
    for (const char* part : {"3D/3dmodel.model", "[Content_Types].xml", "_rels/.rels"}) {
      CAPTURE(part);
      CHECK(bytes.find(part) != std::string::npos);  // the central directory names every part
    }
#ifndef DUPLEXFIT_SANITIZED
    // Read back with lib3mf (not in the sanitizer build: lib3mf 1.8's reader leaks libzip sources and
    // entries on every read, and LeakSanitizer's fast unwinder cannot see past libzip's frames to a
    // suppression; writing is leak-free and checked there).
    const Mesh back = readMesh(path);
    REQUIRE(back.vertices.rows() == m.vertices.rows());
    REQUIRE(back.faces.rows() == m.faces.rows());
    CHECK(back.faces == m.faces);
    CHECK(back.vertices == m.vertices.cast<float>().cast<double>());
    const MeshTopology t = analyzeTopology(back);
    CHECK(t.watertight());
    CHECK(t.oriented());
#endif
    // The same mesh gives the same file (UUIDs from the content); another mesh another one.
    writeMesh(dir.file("again.3mf"), m);
    CHECK(readBytes(dir.file("again.3mf")) == bytes);
    writeMesh(dir.file("cube.3mf"), testing::cube());
    CHECK(readBytes(dir.file("cube.3mf")) != bytes);
    // Bad input: a file that is no 3MF is an IoError naming it; nothing half-written on a bad mesh.
    testing::writeBytes(dir.file("junk.3mf"), "not a zip at all");
#ifndef DUPLEXFIT_SANITIZED  // (lib3mf's reader, as above)
    CHECK_THROWS_WITH_AS(readMesh(dir.file("junk.3mf")), doctest::Contains("junk.3mf"), IoError);
#endif
    Mesh bad = m;
    bad.faces(2, 1) = 99;
    CHECK_THROWS_AS(writeMesh(dir.file("bad.3mf"), bad), InvalidArgument);
    CHECK(readBytes(dir.file("bad.3mf")).empty());
  }

  TEST_CASE("mesh io: without lib3mf, 3MF is a clear error") {
    if (mesh3mfAvailable()) DUPLEXFIT_SKIP("this build has lib3mf (the error cannot happen)");
    TempDir dir;
    CHECK_THROWS_WITH_AS(writeMesh(dir.file("part.3mf"), testing::cube()), doctest::Contains("lib3mf"), InvalidArgument);
    CHECK(dir.entries().empty());
  }
}
