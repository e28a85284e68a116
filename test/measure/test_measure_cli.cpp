// `duplexfit measure` and `duplexfit check` run as a user would, on small meshes written to a temporary
// folder: JSON output, exit codes with and without --strict, and bad input.
#include <doctest/doctest.h>

#include <string>

#include "cli_runner.hpp"
#include "duplexfit/io.hpp"
#include "io/io_test_util.hpp"
#include "json_report.hpp"
#include "measure/measure_shapes.hpp"

namespace {

using namespace duplexfit;
using testing::CliRun;
using testing::Json;
using testing::jsonAt;
using testing::jsonNumber;

CliRun run(const std::string& args) { return testing::runCli(args); }

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST_SUITE("measure") {

TEST_CASE("cli: measure and check on small meshes, as tables and JSON") {
  DUPLEXFIT_REQUIRE_CLI();
  const testing::TempDir dir;
  const std::string inner = dir.file("inner.obj"), outer = dir.file("outer.obj"), holed = dir.file("holed.ply");
  writeMesh(inner, testing::icosphere(2, 0.9));
  writeMesh(outer, testing::icosphere(2, 1.0));
  Mesh h = testing::icosphere(2, 1.0);
  h.faces.conservativeResize(h.faces.rows() - 1, 3);
  writeMesh(holed, h);

  CliRun r = run("measure " + inner + " " + outer + " --json --samples 3 --seed 7 --quiet");
  CHECK(r.status == 0);
  INFO(r.out << r.err);
  Json j = testing::parseJson(r.out);
  CHECK(jsonAt(j, "/mode") == "distance");
  CHECK(jsonAt(j, "/forward").is_object());
  CHECK(jsonAt(j, "/backward").is_object());
  CHECK(jsonNumber(j, "/hausdorff") == doctest::Approx(0.1).epsilon(0.15));
  CHECK(jsonAt(j, "/seed") == 7);
  CHECK(jsonNumber(j, "/hausdorff_rel") == doctest::Approx(jsonNumber(j, "/hausdorff") / jsonNumber(j, "/diagonal_b")));
  CHECK(r.err.empty());

  r = run("measure " + inner + " " + outer + " --samples 2");
  CHECK(r.status == 0);
  CHECK(has(r.out, "forward"));
  CHECK(has(r.out, "Hausdorff"));

  r = run("measure " + inner + " --offset-of " + outer + " --delta 0.1 --json --quiet");
  CHECK(r.status == 0);
  j = testing::parseJson(r.out);
  CHECK(jsonAt(j, "/mode") == "offset");
  CHECK(jsonAt(j, "/wrong_side") == 0);
  CHECK(jsonNumber(j, "/delta") == doctest::Approx(0.1));
  r = run("measure " + inner + " --offset-of " + outer + " --delta=-0.1 --quiet");
  CHECK(r.status == 0);
  CHECK(has(r.out, "wrong side of S"));
  CHECK(has(r.out, "100.0000 %"));

  r = run("check " + outer + " --json --strict --quiet");
  CHECK(r.status == 0);
  j = testing::parseJson(r.out);
  CHECK(jsonAt(j, "/valid") == true);
  CHECK(jsonAt(j, "/genus") == 0);
  CHECK(jsonAt(j, "/self_intersections") == 0);
  CHECK(jsonAt(j, "/euler_characteristic") == 2);

  r = run("check " + holed + " --quiet");
  CHECK(r.status == 0);
  CHECK(has(r.out, "watertight             no"));
  r = run("check " + holed + " --json --strict --quiet");
  CHECK(r.status == 4);
  j = testing::parseJson(r.out);
  CHECK(jsonAt(j, "/watertight") == false);
  CHECK(jsonAt(j, "/boundary_loops") == 1);
}

TEST_CASE("cli: bad input to measure and check is a clear error with the right exit code") {
  DUPLEXFIT_REQUIRE_CLI();
  const testing::TempDir dir;
  const std::string good = dir.file("good.obj");
  writeMesh(good, testing::icosphere(1, 1.0));
  const std::string badIndex = dir.file("bad-index.obj");
  testing::writeBytes(badIndex, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n");
  CliRun r = run("measure " + good + " " + badIndex);
  CHECK(r.status == 2);
  CHECK(has(r.err, "bad-index.obj"));
  CHECK(r.out.empty());

  const std::string noFaces = dir.file("no-faces.obj");
  testing::writeBytes(noFaces, "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  r = run("check " + noFaces);
  CHECK(r.status != 0);
  CHECK(has(r.err, "no-faces.obj"));
  CHECK(has(r.err, "no faces"));

  r = run("measure " + good + " " + good + " --samples 0");
  CHECK(r.status == 1);
  CHECK(has(r.err, "--samples"));
  r = run("measure " + good + " " + dir.file("missing.ply"));
  CHECK(r.status == 2);
  CHECK(has(r.err, "missing.ply"));
  r = run("measure " + good + " --offset-of " + good);
  CHECK(r.status == 1);
  CHECK(has(r.err, "--delta"));
  r = run("measure " + good);
  CHECK(r.status == 1);
  r = run("check " + good + " --bogus");
  CHECK(r.status == 1);
  CHECK(has(r.err, "--bogus"));
}

}  // TEST_SUITE
