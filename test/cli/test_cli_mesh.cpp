// `duplexfit fit` on a triangle mesh, as a user with an STL would run it: an icosphere written as binary and
// ascii STL, OBJ and PLY fitted end to end (the same samples from every format, report.json's input_mesh),
// and bad meshes reported clearly: open (a warning; --strict an error), inconsistently oriented (an error
// naming the faces; --mesh-reorient fixes it), inside out (flipped, and said), empty and zero-area files.
#include <doctest/doctest.h>

#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>

#include "cli_runner.hpp"
#include "measure/measure_shapes.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh.hpp"
#include "json_report.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using namespace duplexfit;

namespace {

using testing::CliRun;
using testing::Json;
using testing::jsonAt;

constexpr const char* kFit = " --offset 0.1 --sample-points 3000 --resolution 40 --quiet";

/// An ascii STL of the mesh, corners written with 9 significant digits (float32 round trip, as binary STL).
void writeAsciiStl(const fs::path& path, const Mesh& m) {
  std::ostringstream s;
  s.precision(9);
  s << "solid icosphere\n";
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    s << "  facet normal 0 0 0\n    outer loop\n";
    for (int k = 0; k < 3; ++k) {
      const Eigen::RowVector3f p = m.vertices.row(m.faces(f, k)).cast<float>();
      s << "      vertex " << p.x() << " " << p.y() << " " << p.z() << "\n";
    }
    s << "    endloop\n  endfacet\n";
  }
  s << "endsolid icosphere\n";
  REQUIRE(testing::writeFile(path, s.str()));
}

std::size_t filesIn(const fs::path& dir) {
  if (!fs::exists(dir)) return 0;
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.is_regular_file() || e.is_directory() ? 1 : 0;
  return n;
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// The mesh with every face's orientation reversed.
Mesh reversed(Mesh m) {
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) std::swap(m.faces(f, 1), m.faces(f, 2));
  return m;
}

}  // namespace

TEST_SUITE("cli") {
  TEST_CASE("cli: fit part.stl samples the mesh and fits it; binary and ascii STL, OBJ and PLY give the same") {
    DUPLEXFIT_REQUIRE_CLI();
    testing::TempDir dir("duplexfit-cli-mesh");
    const Mesh sphere = testing::icosphere(3, 0.5);  // 1280 faces
    REQUIRE(signedVolume(sphere) > 0.0);
    writeMesh(dir.file("part.stl"), sphere);
    writeAsciiStl(dir / "ascii.stl", sphere);
    writeMesh(dir.file("part.obj"), sphere);
    writeMesh(dir.file("part.ply"), sphere);

    const fs::path out = dir / "stl";
    const CliRun r = testing::runCli("fit " + dir.file("part.stl") + kFit + " --strict -o " + out.string());
    INFO("stderr: " << r.err);
    REQUIRE(r.status == 0);
    CHECK(has(r.out, "mesh of 1280 triangles sampled into 3000 points"));
    for (const char* f : {"zero.ply", "offset1.ply", "field.dpxf", "report.json"}) CHECK(fs::exists(out / f));
    const Json report = testing::readJsonFile(out / "report.json");
    CHECK(jsonAt(report, "/input") == dir.file("part.stl"));
    CHECK(jsonAt(report, "/points") == 3000);
    CHECK(jsonAt(report, "/input_mesh/format") == "stl");
    CHECK(jsonAt(report, "/input_mesh/faces") == 1280);
    CHECK(jsonAt(report, "/input_mesh/watertight") == true);
    CHECK(jsonAt(report, "/input_mesh/oriented") == true);
    CHECK(jsonAt(report, "/input_mesh/boundary_edges") == 0);
    CHECK(jsonAt(report, "/input_mesh/flipped") == false);
    CHECK(jsonAt(report, "/input_mesh/samples") == 3000);
    CHECK(jsonAt(report, "/input_mesh/density_rule") == "points");
    CHECK(jsonAt(report, "/input_mesh/warnings") == Json::array());
    CHECK(jsonAt(report, "/self_check/ok") == true);

    // The surfaces: the zero level on the icosphere (its faces lie within 0.5·(1 − cos) ≈ 0.003 of the
    // sphere), the offset 0.1 inside it.
    const Mesh zero = readMesh((out / "zero.ply").string());
    const Mesh offset = readMesh((out / "offset1.ply").string());
    CHECK(analyzeTopology(zero).watertight());
    CHECK(analyzeTopology(offset).components == 1);
    const DistanceReport toInput = measureDistance(zero, sphere);
    MESSAGE("fit of the icosphere STL: zero level to the input mesh: Hausdorff " << toInput.hausdorff);
    CHECK(toInput.hausdorff < 0.005);
    const OffsetReport off = measureOffset(offset, zero, 0.1);
    CHECK(off.deviation.max < 0.01);
    CHECK(off.wrongSide == 0);

    // Every format reads the same welded mesh, hence the same samples and the same fit (up to the float32
    // rounding of the STL and PLY corners: OBJ keeps the doubles, ascii STL the 9-digit decimals).
    for (const char* name : {"ascii.stl", "part.obj", "part.ply"}) {
      CAPTURE(name);
      const fs::path o = dir / (std::string(name) + ".out");
      const CliRun run = testing::runCli("fit " + dir.file(name) + kFit + " -o " + o.string());
      INFO("stderr: " << run.err);
      REQUIRE(run.status == 0);
      const Json rep = testing::readJsonFile(o / "report.json");
      CHECK(jsonAt(rep, "/input_mesh/faces") == 1280);
      CHECK(jsonAt(rep, "/input_mesh/samples") == 3000);
      const DistanceReport same = measureDistance(readMesh((o / "zero.ply").string()), zero);
      CHECK(same.hausdorff < 1e-4);
    }
    CHECK(jsonAt(testing::readJsonFile(dir / "part.obj.out" / "report.json"), "/input_mesh/format") == "obj");

    // --input-type cloud reads the PLY's vertices as a cloud: it has no normals, so that is an error.
    const CliRun cloud = testing::runCli("fit " + dir.file("part.ply") + kFit + " --input-type cloud -o " +
                                         (dir / "cloud").string());
    CHECK(cloud.status == 2);
    CHECK(has(cloud.err, "normals"));
    CHECK(filesIn(dir / "cloud") == 0);
    const CliRun bad = testing::runCli("fit " + dir.file("part.stl") + " --offset 0.1 --sample-points 100 "
                                       "--sample-spacing 0.1 -o " + (dir / "bad").string());
    CHECK(bad.status == 1);
    CHECK(has(bad.err, "not both"));
    CHECK(testing::runCli("fit " + dir.file("part.stl") + " --offset 0.1 --input-type surface").status == 1);
    const CliRun inward = testing::runCli("fit " + dir.file("part.stl") + kFit + " --normals-inward -o " +
                                          (dir / "inward").string());
    CHECK(inward.status == 1);
    CHECK(has(inward.err, dir.file("part.stl") + ": --normals-inward applies to clouds"));
  }

  TEST_CASE("cli: bad meshes are reported clearly: open, inconsistent, inside out, empty, zero area") {
    DUPLEXFIT_REQUIRE_CLI();
    testing::TempDir dir("duplexfit-cli-badmesh");
    const Mesh sphere = testing::icosphere(3, 0.5);

    // Open: a warning naming the file and the count; the fit still runs. --strict: an error, nothing written.
    std::vector<char> keep(static_cast<std::size_t>(sphere.faces.rows()), 1);
    keep[0] = 0;  // one triangle missing: three boundary edges
    writeMesh(dir.file("open.stl"), keepFaces(sphere, keep));
    CliRun r = testing::runCli("fit " + dir.file("open.stl") + " --offset 0.1 --sample-points 3000 --resolution 40 -o " +
                               (dir / "open").string());
    INFO("stderr: " << r.err);
    CHECK(r.status == 0);
    CHECK(has(r.err, "warning: " + dir.file("open.stl") + ": the mesh is open: 3 boundary edge(s)"));
    CHECK(jsonAt(testing::readJsonFile(dir / "open" / "report.json"), "/input_mesh/boundary_edges") == 3);
    CHECK(jsonAt(testing::readJsonFile(dir / "open" / "report.json"), "/input_mesh/warnings").size() == 1);
    r = testing::runCli("fit " + dir.file("open.stl") + kFit + " --strict -o " + (dir / "open-strict").string());
    CHECK(r.status == 1);
    CHECK(has(r.err, dir.file("open.stl") + ": the mesh is open: 3 boundary edge(s)"));
    CHECK(filesIn(dir / "open-strict") == 0);

    // Inconsistently oriented: an error naming the file and the faces; --mesh-reorient turns them.
    Mesh turned = sphere;
    for (const Eigen::Index f : {5, 6, 7}) std::swap(turned.faces(f, 1), turned.faces(f, 2));
    writeMesh(dir.file("turned.stl"), turned);
    r = testing::runCli("fit " + dir.file("turned.stl") + kFit + " -o " + (dir / "turned").string());
    CHECK(r.status == 1);
    CHECK(has(r.err, dir.file("turned.stl") + ": the mesh is not consistently oriented"));
    CHECK(has(r.err, "(first: faces "));
    CHECK(has(r.err, "--mesh-reorient"));
    CHECK(filesIn(dir / "turned") == 0);
    r = testing::runCli("fit " + dir.file("turned.stl") + kFit + " --mesh-reorient --strict -o " +
                        (dir / "turned").string());
    CHECK(r.status == 0);
    const Json t = testing::readJsonFile(dir / "turned" / "report.json");
    CHECK(jsonAt(t, "/input_mesh/reoriented_faces") == 3);
    CHECK(jsonAt(t, "/input_mesh/inconsistent_after") == 0);
    CHECK(jsonAt(t, "/input_mesh/orientation") == "reorient");
    CHECK(jsonAt(t, "/self_check/ok") == true);
    // --estimate-normals replaces the face normals, so the orientation does not matter there.
    r = testing::runCli("fit " + dir.file("turned.stl") + kFit + " --estimate-normals -o " + (dir / "est").string());
    CHECK(r.status == 0);
    CHECK(jsonAt(testing::readJsonFile(dir / "est" / "report.json"), "/input_mesh/orientation") == "keep");

    // Inside out: the normals are flipped (and said); the offset is still inside.
    writeMesh(dir.file("inside.stl"), reversed(sphere));
    r = testing::runCli("fit " + dir.file("inside.stl") + " --offset 0.1 --sample-points 3000 --resolution 40 -o " +
                        (dir / "inside").string());
    CHECK(r.status == 0);
    CHECK(has(r.err, dir.file("inside.stl") + ": the mesh is inside out"));
    CHECK(jsonAt(testing::readJsonFile(dir / "inside" / "report.json"), "/input_mesh/flipped") == true);
    const Mesh zero = readMesh((dir / "inside" / "zero.ply").string());
    const Mesh offset = readMesh((dir / "inside" / "offset1.ply").string());
    CHECK(signedVolume(zero) > 0.0);
    CHECK(signedVolume(offset) > 0.0);
    CHECK(signedVolume(offset) < 0.7 * signedVolume(zero));

    // No faces, zero area: errors naming the file, exit 1, nothing written.
    std::string empty(80, ' ');
    empty += std::string(4, '\0');  // a binary STL with 0 triangles
    REQUIRE(testing::writeFile(dir / "empty.stl", empty));
    r = testing::runCli("fit " + dir.file("empty.stl") + kFit + " -o " + (dir / "empty").string());
    CHECK(r.status == 1);
    CHECK(has(r.err, dir.file("empty.stl") + ": the mesh has no faces"));
    CHECK(filesIn(dir / "empty") == 0);
    Mesh flat;
    flat.vertices.resize(3, 3);
    flat.vertices << 0, 0, 0, 1, 1, 1, 2, 2, 2;
    flat.faces.resize(1, 3);
    flat.faces << 0, 1, 2;
    writeMesh(dir.file("flat.obj"), flat);
    r = testing::runCli("fit " + dir.file("flat.obj") + kFit + " -o " + (dir / "flat").string());
    CHECK(r.status == 1);
    CHECK(has(r.err, dir.file("flat.obj") + ": the mesh has zero area"));
    // A truncated STL is a read error (exit 2) naming the file.
    std::string stl = testing::readFile(dir / "open.stl");
    stl.resize(stl.size() - 20);
    REQUIRE(testing::writeFile(dir / "cut.stl", stl));
    r = testing::runCli("fit " + dir.file("cut.stl") + kFit + " -o " + (dir / "cut").string());
    CHECK(r.status == 2);
    CHECK(has(r.err, dir.file("cut.stl")));
  }
}
