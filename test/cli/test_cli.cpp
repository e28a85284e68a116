// The duplexfit command line, run as a user would: outputs of fit and mesh, and bad input that must give a
// clear error naming the file and element, a non-zero exit status and no partial output.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "cli_runner.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/io.hpp"
#include "json_report.hpp"
#include "shapes.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using namespace duplexfit;

namespace {

using testing::CliRun;
using testing::Json;
using testing::jsonAt;

fs::path scratch(const std::string& name) { return testing::scratchDir("duplexfit-cli-test", name); }

CliRun cli(const std::string& args) { return testing::runCli(args); }

std::string readBytes(const fs::path& p) { return testing::readFile(p); }

void writeText(const fs::path& p, const std::string& text) { REQUIRE(testing::writeFile(p, text)); }

// A small valid cloud (a sphere) as binary PLY.
fs::path sphereCloud(const fs::path& dir, int n = 800) {
  Points normals;
  Points p = testing::fibonacciSphere(n, 0.5, &normals);
  const fs::path path = dir / "sphere.ply";
  writePointCloud(path.string(), PointSet(p, normals));
  return path;
}

std::size_t filesIn(const fs::path& dir) {
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.is_regular_file() || e.is_directory() ? 1 : 0;
  return n;
}

// Expects a failing fit: non-zero status, the message mentions every part, the output folder stays empty.
void expectFitError(const std::string& input, const std::string& options, std::initializer_list<const char*> parts) {
  const fs::path out = scratch("out-err");
  const CliRun r = cli("fit " + input + " " + options + " -o " + out.string() + " --quiet");
  INFO("stderr: " << r.err);
  CHECK(r.status != 0);
  for (const char* part : parts) CHECK(r.err.find(part) != std::string::npos);
  CHECK(filesIn(out) == 0);
}

}  // namespace

TEST_SUITE("cli") {
  TEST_CASE("cli: fit writes both meshes, the field and the report; mesh re-extracts a level set") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("fit");
    const fs::path input = sphereCloud(dir);
    const fs::path out = dir / "out";
    const CliRun r = cli("fit " + input.string() + " --offset 0.1 -o " + out.string() + " --quiet --strict");
    INFO("stderr: " << r.err);
    REQUIRE(r.status == 0);
    for (const char* f : {"zero.ply", "offset1.ply", "field.dpxf", "report.json"}) CHECK(fs::exists(out / f));
    CHECK(filesIn(out) == 4);  // nothing else left behind (no staging folder)
    const MeshTopology zero = analyzeTopology(readMesh((out / "zero.ply").string()));
    const MeshTopology off = analyzeTopology(readMesh((out / "offset1.ply").string()));
    CHECK(zero.components == 1);
    CHECK(off.components == 1);
    CHECK(off.watertight());
    const Json report = testing::readJsonFile(out / "report.json");
    const Json levels = jsonAt(report, "/level_reports");
    CHECK(levels.is_array());
    CHECK_FALSE(levels.empty());
    CHECK(jsonAt(report, "/E0").is_number());
    // The self-check ran (input points tested against the zero level) and found nothing.
    CHECK(jsonAt(report, "/self_check").is_object());
    CHECK(jsonAt(report, "/self_check/ok") == true);
    CHECK(jsonAt(report, "/self_check/points_checked") == true);
    CHECK(jsonAt(report, "/self_check/issues") == Json::array());
    CHECK(testing::jsonValuesOf(report, "why").empty());  // no component issue anywhere

    const CliRun m = cli("mesh " + (out / "field.dpxf").string() + " --iso 0.05 -o " + (dir / "half.obj").string() + " --quiet");
    CHECK(m.status == 0);
    CHECK(analyzeTopology(readMesh((dir / "half.obj").string())).components == 1);
    const CliRun mc = cli("mesh " + (out / "field.dpxf").string() + " --min-component 0.01 -o " + (dir / "min.obj").string() +
                          " --quiet");
    CHECK(mc.status == 0);
    CHECK(analyzeTopology(readMesh((dir / "min.obj").string())).components == 1);

    // The robust-field mechanisms are counted per level and can be switched off.
    for (const Json& level : levels) {
      CHECK(jsonAt(level, "/anchors").is_object());
      CHECK(jsonAt(level, "/offset_medial").is_array());
    }
    const CliRun plain = cli("fit " + input.string() + " --offset 0.1 --no-anchors --no-medial -o " + (dir / "plain").string() +
                             " --quiet --resolution 32");
    REQUIRE(plain.status == 0);
    const Json plainReport = testing::readJsonFile(dir / "plain" / "report.json");
    // Every per-level count of anchors and medial points is 0 (every value of the key, wherever it is).
    auto allZero = [](const Json& doc, const std::string& key) {
      const std::vector<Json> values = testing::jsonValuesOf(doc, key);
      return !values.empty() && std::all_of(values.begin(), values.end(), [](const Json& v) {
        return v.is_number_integer() && v.get<long long>() == 0;
      });
    };
    CHECK(allZero(plainReport, "inside"));
    CHECK(allZero(plainReport, "outside"));
    CHECK(allZero(plainReport, "off_surface_medial"));
    CHECK_FALSE(allZero(report, "outside"));  // the default fit placed anchors

    const CliRun rel = cli("fit " + input.string() + " --offset 0.1,-0.05 --offset-rel -o " + (dir / "rel").string() + " --quiet --format stl");
    CHECK(rel.status == 0);
    CHECK(fs::exists(dir / "rel" / "offset2.stl"));
  }

  TEST_CASE("cli: fit --separate writes one field per surface and a report in separate mode") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("separate");
    const fs::path input = sphereCloud(dir);
    const fs::path out = dir / "out";
    const CliRun r = cli("fit " + input.string() + " --offset 0.1 --separate -o " + out.string() + " --quiet --strict");
    INFO("stderr: " << r.err);
    REQUIRE(r.status == 0);
    for (const char* f : {"zero.ply", "offset1.ply", "field.dpxf", "field_offset1.dpxf", "report.json"}) {
      CHECK(fs::exists(out / f));
    }
    CHECK(filesIn(out) == 5);
    const Json report = testing::readJsonFile(out / "report.json");
    CHECK(jsonAt(report, "/mode") == "separate");
    CHECK(jsonAt(report, "/fits").is_array());
    CHECK(jsonAt(report, "/self_check").is_object());
    CHECK(jsonAt(report, "/self_check/ok") == true);
    // The two fields are independent: each has its own 0-level (surface radius 0.5, offset radius 0.4).
    const ImplicitField zero = ImplicitField::load((out / "field.dpxf").string());
    const ImplicitField off = ImplicitField::load((out / "field_offset1.dpxf").string());
    CHECK(std::abs(zero.value(Eigen::Vector3d(0.5, 0, 0))) < 2e-3);
    CHECK(std::abs(off.value(Eigen::Vector3d(0.4, 0, 0))) < 2e-3);
    CHECK(std::abs(off.value(Eigen::Vector3d(0.5, 0, 0))) > 0.02);
    const MeshTopology t = analyzeTopology(readMesh((out / "offset1.ply").string()));
    CHECK(t.components == 1);
    CHECK(t.watertight());
  }

  TEST_CASE("cli: bad clouds give a clear error naming the file and element, and no output") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("bad");
    const std::string header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                               "property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n";
    writeText(dir / "empty.ply", "");
    expectFitError((dir / "empty.ply").string(), "--offset 0.1", {"empty.ply"});
    writeText(dir / "short.ply", header + "0 0 0 0 0 1\n1 0 0 0 0 1\n");
    expectFitError((dir / "short.ply").string(), "--offset 0.1", {"short.ply"});
    writeText(dir / "nan.ply", header + "0 0 0 0 0 1\nnan 0 0 0 0 1\n1 1 1 0 0 1\n");
    expectFitError((dir / "nan.ply").string(), "--offset 0.1", {"nan.ply", "1"});
    writeText(dir / "nonormals.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                     "property float z\nend_header\n0 0 0\n");
    expectFitError((dir / "nonormals.ply").string(), "--offset 0.1", {"nonormals.ply", "normal"});
    // Truncated binary.
    const fs::path good = sphereCloud(dir);
    const std::string bytes = readBytes(good);
    writeText(dir / "cut.ply", bytes.substr(0, bytes.size() - 100));
    expectFitError((dir / "cut.ply").string(), "--offset 0.1", {"cut.ply"});
    // Too few points, all coincident, collinear, zero normals.
    std::string few = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                      "property float nx\nproperty float ny\nproperty float nz\nend_header\n";
    for (int i = 0; i < 5; ++i) few += std::to_string(i) + " 0 0 0 0 1\n";
    writeText(dir / "few.ply", few);
    expectFitError((dir / "few.ply").string(), "--offset 0.1", {"few.ply", "10"});
    std::string line = "x y z nx ny nz\n";
    std::string same, zeros;
    for (int i = 0; i < 20; ++i) {
      line += std::to_string(i) + " " + std::to_string(2 * i) + " 0 0 0 1\n";
      same += "1 2 3 0 0 1\n";
      zeros += std::to_string(i % 5) + " " + std::to_string(i / 5) + " " + std::to_string(i % 3) + " 0 0 0\n";
    }
    writeText(dir / "line.xyz", line.substr(line.find('\n') + 1));
    expectFitError((dir / "line.xyz").string(), "--offset 0.1", {"line.xyz", "line"});
    writeText(dir / "same.xyz", same);
    expectFitError((dir / "same.xyz").string(), "--offset 0.1", {"same.xyz"});
    writeText(dir / "zeros.xyz", zeros);
    expectFitError((dir / "zeros.xyz").string(), "--offset 0.1", {"zeros.xyz", "normal"});
  }

  TEST_CASE("cli: bad options, an unwritable output and bad field files are clear errors") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("opts");
    const std::string input = sphereCloud(dir).string();
    expectFitError(input, "--offset 0", {"offset"});
    expectFitError(input, "--offset 5", {"offset", "largest side"});
    expectFitError(input, "--offset abc", {"abc"});
    expectFitError(input, "--offset 0.1 --min-component 1.5", {"min-component"});
    expectFitError(input, "", {"offset"});
    expectFitError(input, "--offset 0.1 --device no-such-device", {"no-such-device", "available devices"});
    // An output path below a regular file cannot be created.
    writeText(dir / "file", "x");
    const CliRun r = cli("fit " + input + " --offset 0.1 -o " + (dir / "file" / "sub").string() + " --quiet");
    CHECK(r.status == 2);
    CHECK(r.err.find("output folder") != std::string::npos);
    // Field files: corrupt, truncated, unknown version.
    const fs::path out = dir / "out";
    REQUIRE(cli("fit " + input + " --offset 0.1 -o " + out.string() + " --quiet").status == 0);
    const std::string bytes = readBytes(out / "field.dpxf");
    std::string corrupt = bytes;
    corrupt[bytes.size() / 2] = static_cast<char>(corrupt[bytes.size() / 2] ^ 1);
    writeText(dir / "corrupt.dpxf", corrupt);
    writeText(dir / "cut.dpxf", bytes.substr(0, bytes.size() / 3));
    std::string v2 = bytes;
    v2[8] = 2;
    writeText(dir / "v2.dpxf", v2);
    for (const char* name : {"corrupt.dpxf", "cut.dpxf", "v2.dpxf"}) {
      const fs::path mesh = dir / (std::string(name) + ".ply");
      const CliRun m = cli(std::string("mesh ") + (dir / name).string() + " -o " + mesh.string() + " --quiet");
      INFO(name << ": " << m.err);
      CHECK(m.status == 2);
      CHECK(m.err.find(name) != std::string::npos);
      CHECK_FALSE(fs::exists(mesh));
    }
  }
}

