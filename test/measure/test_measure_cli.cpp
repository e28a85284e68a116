// `duplexfit measure` and `duplexfit check` run as a user would, on small meshes written to a temporary
// folder: JSON output, exit codes with and without --strict, and bad input.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/wait.h>

#include "duplexfit/io.hpp"
#include "io/io_test_util.hpp"
#include "measure/measure_shapes.hpp"

#ifdef DUPLEXFIT_CLI_PATH

namespace {

using namespace duplexfit;

struct Run {
  int status = -1;
  std::string out, err;
};

Run run(const testing::TempDir& dir, const std::string& args) {
  const std::string out = dir.file("stdout.txt"), err = dir.file("stderr.txt");
  const std::string cmd = std::string(DUPLEXFIT_CLI_PATH) + " " + args + " > " + out + " 2> " + err;
  const int raw = std::system(cmd.c_str());
  Run r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = testing::readBytes(out);
  r.err = testing::readBytes(err);
  return r;
}

/// The number after "key": in JSON text (NaN when missing).
double jsonNumber(const std::string& json, const std::string& key) {
  const auto at = json.find("\"" + key + "\": ");
  if (at == std::string::npos) return std::nan("");
  return std::strtod(json.c_str() + at + key.size() + 4, nullptr);
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST_SUITE("measure") {

TEST_CASE("cli: measure and check on small meshes, as tables and JSON") {
  const testing::TempDir dir;
  const std::string inner = dir.file("inner.obj"), outer = dir.file("outer.obj"), holed = dir.file("holed.ply");
  writeMesh(inner, testing::icosphere(2, 0.9));
  writeMesh(outer, testing::icosphere(2, 1.0));
  Mesh h = testing::icosphere(2, 1.0);
  h.faces.conservativeResize(h.faces.rows() - 1, 3);
  writeMesh(holed, h);

  Run r = run(dir, "measure " + inner + " " + outer + " --json --samples 3 --seed 7 --quiet");
  CHECK(r.status == 0);
  INFO(r.out << r.err);
  CHECK(has(r.out, "\"mode\": \"distance\""));
  CHECK(has(r.out, "\"forward\""));
  CHECK(has(r.out, "\"backward\""));
  CHECK(jsonNumber(r.out, "hausdorff") == doctest::Approx(0.1).epsilon(0.15));
  CHECK(jsonNumber(r.out, "seed") == 7);
  CHECK(jsonNumber(r.out, "hausdorff_rel") == doctest::Approx(jsonNumber(r.out, "hausdorff") / jsonNumber(r.out, "diagonal_b")));
  CHECK(r.err.empty());

  r = run(dir, "measure " + inner + " " + outer + " --samples 2");
  CHECK(r.status == 0);
  CHECK(has(r.out, "forward"));
  CHECK(has(r.out, "Hausdorff"));

  r = run(dir, "measure " + inner + " --offset-of " + outer + " --delta 0.1 --json --quiet");
  CHECK(r.status == 0);
  CHECK(has(r.out, "\"mode\": \"offset\""));
  CHECK(jsonNumber(r.out, "wrong_side") == 0);
  CHECK(jsonNumber(r.out, "delta") == doctest::Approx(0.1));
  r = run(dir, "measure " + inner + " --offset-of " + outer + " --delta=-0.1 --quiet");
  CHECK(r.status == 0);
  CHECK(has(r.out, "wrong side of S"));
  CHECK(has(r.out, "100.0000 %"));

  r = run(dir, "check " + outer + " --json --strict --quiet");
  CHECK(r.status == 0);
  CHECK(has(r.out, "\"valid\": true"));
  CHECK(has(r.out, "\"genus\": 0"));
  CHECK(has(r.out, "\"self_intersections\": 0"));
  CHECK(jsonNumber(r.out, "euler_characteristic") == 2);

  r = run(dir, "check " + holed + " --quiet");
  CHECK(r.status == 0);
  CHECK(has(r.out, "watertight             no"));
  r = run(dir, "check " + holed + " --json --strict --quiet");
  CHECK(r.status == 4);
  CHECK(has(r.out, "\"watertight\": false"));
  CHECK(jsonNumber(r.out, "boundary_loops") == 1);
}

TEST_CASE("cli: bad input to measure and check is a clear error with the right exit code") {
  const testing::TempDir dir;
  const std::string good = dir.file("good.obj");
  writeMesh(good, testing::icosphere(1, 1.0));
  const std::string badIndex = dir.file("bad-index.obj");
  testing::writeBytes(badIndex, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n");
  Run r = run(dir, "measure " + good + " " + badIndex);
  CHECK(r.status == 2);
  CHECK(has(r.err, "bad-index.obj"));
  CHECK(r.out.empty());

  const std::string noFaces = dir.file("no-faces.obj");
  testing::writeBytes(noFaces, "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  r = run(dir, "check " + noFaces);
  CHECK(r.status != 0);
  CHECK(has(r.err, "no-faces.obj"));
  CHECK(has(r.err, "no faces"));

  r = run(dir, "measure " + good + " " + good + " --samples 0");
  CHECK(r.status == 1);
  CHECK(has(r.err, "--samples"));
  r = run(dir, "measure " + good + " " + dir.file("missing.ply"));
  CHECK(r.status == 2);
  CHECK(has(r.err, "missing.ply"));
  r = run(dir, "measure " + good + " --offset-of " + good);
  CHECK(r.status == 1);
  CHECK(has(r.err, "--delta"));
  r = run(dir, "measure " + good);
  CHECK(r.status == 1);
  r = run(dir, "check " + good + " --bogus");
  CHECK(r.status == 1);
  CHECK(has(r.err, "--bogus"));
}

}  // TEST_SUITE

#endif  // DUPLEXFIT_CLI_PATH
