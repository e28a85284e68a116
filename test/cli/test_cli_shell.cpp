// The printable shell on the command line: fit --shell (with a drain hole) writes shell.ply and report.json's
// "shell" block, mesh --shell rebuilds it from the saved field, slice honours the same holes, and bad input
// (no inward offset, a malformed hole) is a usage error that writes nothing.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "cli_runner.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh.hpp"
#include "json_report.hpp"
#include "shapes.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using namespace duplexfit;

namespace {

using testing::CliRun;
using testing::Json;
using testing::jsonAt;
using testing::jsonNumber;

fs::path scratch(const std::string& name) { return testing::scratchDir("duplexfit-cli-shell-test", name); }

/// A sphere of radius 0.5 (800 points with normals) as binary PLY.
fs::path sphereCloud(const fs::path& dir) {
  Points normals;
  const Points p = testing::fibonacciSphere(800, 0.5, &normals);
  const fs::path path = dir / "sphere.ply";
  writePointCloud(path.string(), PointSet(p, normals));
  return path;
}

std::size_t filesIn(const fs::path& dir) {
  std::size_t n = 0;
  if (!fs::exists(dir)) return 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.is_regular_file() || e.is_directory() ? 1 : 0;
  return n;
}

/// The area of the layer nearest to `height` in a slices.json (model coordinates: --place none).
double areaNear(const Json& slices, double height) {
  const Json heights = jsonAt(slices, "/heights"), areas = jsonAt(slices, "/areas");
  REQUIRE(heights.is_array());
  REQUIRE(heights.size() == areas.size());
  std::size_t best = 0;
  for (std::size_t i = 0; i < heights.size(); ++i) {
    if (std::abs(heights[i].get<double>() - height) < std::abs(heights[best].get<double>() - height)) best = i;
  }
  return areas[best].get<double>();
}

}  // namespace

TEST_SUITE("cli") {
  TEST_CASE("cli: fit --shell writes shell.ply and the report's shell block; mesh and slice use the same holes") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("shell");
    const fs::path input = sphereCloud(dir);
    const fs::path out = dir / "out";
    const CliRun r = testing::runCli("fit " + input.string() + " --offset 0.1 --shell --drain-hole 0,0,0,0.08 -o " +
                                     out.string() + " --resolution 64 --quiet --strict");
    INFO("stderr: " << r.err);
    REQUIRE(r.status == 0);
    for (const char* f : {"zero.ply", "offset1.ply", "shell.ply", "field.dpxf", "report.json"}) CHECK(fs::exists(out / f));
    CHECK(filesIn(out) == 5);
    CHECK(r.out.find("shell.ply") != std::string::npos);
    const Mesh shell = readMesh((out / "shell.ply").string());
    const MeshTopology t = analyzeTopology(shell);
    CHECK(t.watertight());
    CHECK(t.oriented());
    CHECK(t.components == 1);  // the hole joins the outer and the inner surface
    const Json report = testing::readJsonFile(out / "report.json");
    const Json s = jsonAt(report, "/shell");
    REQUIRE(s.is_object());
    CHECK(jsonAt(s, "/file") == "shell.ply");
    CHECK(jsonAt(s, "/offset") == 0.1);
    CHECK(jsonAt(s, "/inner_surface") == "offset1.ply");
    CHECK(jsonAt(s, "/faces") == t.faces);
    CHECK(jsonAt(s, "/watertight") == true);
    CHECK(jsonAt(s, "/oriented") == true);
    CHECK(jsonAt(s, "/intersects") == false);
    CHECK(jsonAt(s, "/valid") == true);
    CHECK(jsonNumber(s, "/volume") == doctest::Approx(signedVolume(shell)).epsilon(1e-5));
    const double reference = jsonNumber(s, "/zero_minus_offset_volume");
    CHECK(reference == doctest::Approx(4.0 / 3.0 * 3.14159265 * (0.125 - 0.064)).epsilon(0.02));
    CHECK(jsonNumber(s, "/relative_difference") < 0.0);  // the hole's material is gone
    CHECK(jsonNumber(s, "/relative_difference") > -0.05);
    REQUIRE(jsonAt(s, "/drain_holes").size() == 1);
    CHECK(jsonNumber(s, "/drain_holes/0/radius") == 0.08);

    // mesh --shell from the saved field: without holes two components (outer and inner) and the same
    // volume as zero - offset; with the hole the fit's mesh.
    const std::string field = (out / "field.dpxf").string();
    const CliRun m = testing::runCli("mesh " + field + " --shell --iso 0.1 --resolution 64 -o " + (dir / "whole.ply").string() +
                                     " --quiet");
    INFO("mesh stderr: " << m.err);
    REQUIRE(m.status == 0);
    const Mesh whole = readMesh((dir / "whole.ply").string());
    CHECK(analyzeTopology(whole).components == 2);
    CHECK(analyzeTopology(whole).watertight());
    CHECK(signedVolume(whole) == doctest::Approx(reference).epsilon(1e-5));
    const CliRun md = testing::runCli("mesh " + field + " --shell --iso 0.1 --resolution 64 --drain-hole 0,0,0,0.08 -o " +
                                      (dir / "drained.obj").string() + " --quiet");
    REQUIRE(md.status == 0);
    const Mesh drained = readMesh((dir / "drained.obj").string());
    CHECK(analyzeTopology(drained).components == 1);
    CHECK(signedVolume(drained) == doctest::Approx(signedVolume(shell)).epsilon(1e-5));

    // slice --mode shell with the hole: the bottom wall's layer loses about the hole's disc (π 0.08² = 0.02).
    const std::string sliceArgs = "slice " + field + " --mode shell --layer 0.02 --place none --quiet -o ";
    REQUIRE(testing::runCli(sliceArgs + (dir / "plain").string()).status == 0);
    const CliRun sd = testing::runCli(sliceArgs + (dir / "holed").string() + " --drain-hole 0,0,0,0.08");
    INFO("slice stderr: " << sd.err);
    REQUIRE(sd.status == 0);
    const Json plainSlices = testing::readJsonFile(dir / "plain" / "slices.json");
    const Json holedSlices = testing::readJsonFile(dir / "holed" / "slices.json");
    CHECK(jsonAt(holedSlices, "/mode") == "shell");
    CHECK(jsonAt(holedSlices, "/drain_holes").size() == 1);
    CHECK(jsonAt(plainSlices, "/drain_holes").is_null());
    const double lost = areaNear(plainSlices, -0.45) - areaNear(holedSlices, -0.45);
    CHECK(lost == doctest::Approx(3.14159265 * 0.08 * 0.08).epsilon(0.15));
    CHECK(areaNear(plainSlices, 0.2) == doctest::Approx(areaNear(holedSlices, 0.2)).epsilon(1e-6));  // above the hole
    CHECK(testing::runCli(sliceArgs + (dir / "auto").string() + " --drain-hole auto").status == 1);
    CHECK(testing::runCli(sliceArgs + (dir / "zero").string() + " --drain-hole 0,0,0,0.08 --mode zero").status == 1);
  }

  TEST_CASE("cli: --shell without an inward offset and malformed drain holes are usage errors that write nothing") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("shell-bad");
    const std::string input = sphereCloud(dir).string();
    const auto expectUsage = [&](const std::string& options, std::initializer_list<const char*> parts) {
      const fs::path out = dir / "out";
      const CliRun r = testing::runCli("fit " + input + " " + options + " -o " + out.string() + " --quiet");
      INFO(options << ": " << r.err);
      CHECK(r.status == 1);
      for (const char* part : parts) CHECK(r.err.find(part) != std::string::npos);
      CHECK(filesIn(out) == 0);
    };
    expectUsage("--offset -0.05 --shell", {"--shell", "inward offset"});
    expectUsage("--offset -0.05 --drain-hole 0,0,0,0.1", {"--shell", "inward offset"});
    expectUsage("--offset 0.1 --shell --drain-hole 0,0,0", {"--drain-hole"});
    expectUsage("--offset 0.1 --shell --drain-hole 0,0,0,-1", {"--drain-hole"});
    expectUsage("--offset 0.1 --separate --drain-hole auto", {"--drain-hole", "--separate"});
    // mesh --shell needs --iso D > 0.
    const CliRun fit = testing::runCli("fit " + input + " --offset 0.1 -o " + (dir / "ok").string() + " --quiet");
    REQUIRE(fit.status == 0);
    const fs::path mesh = dir / "shell.ply";
    const CliRun m = testing::runCli("mesh " + (dir / "ok" / "field.dpxf").string() + " --shell -o " + mesh.string() +
                                     " --quiet");
    CHECK(m.status == 1);
    CHECK(m.err.find("--iso") != std::string::npos);
    CHECK_FALSE(fs::exists(mesh));
  }
}
