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
#include "duplexfit/mesh_finish.hpp"
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
    // The device's launch shape and field kernel, as Device::tuning() describes them.
    const std::string tuning = jsonAt(report, "/device_tuning").get<std::string>();
    CHECK((tuning == "reference" || tuning.find(" field=") != std::string::npos));
    // The self-check ran (input points tested against the zero level) and found nothing.
    CHECK(jsonAt(report, "/self_check").is_object());
    CHECK(jsonAt(report, "/self_check/ok") == true);
    CHECK(jsonAt(report, "/self_check/points_checked") == true);
    CHECK(jsonAt(report, "/self_check/issues") == Json::array());
    CHECK(testing::jsonValuesOf(report, "why").empty());  // no component issue anywhere
    // The offset's thinnest wall to the zero level (measured vertices), about δ = 0.1 on a sphere, where it is
    // and nothing for the zero level; no warning line on the summary.
    CHECK(testing::jsonNumber(report, "/self_check/surfaces/1/thinnest_wall_relative") > 0.9);
    CHECK(testing::jsonNumber(report, "/self_check/surfaces/1/thinnest_wall_relative") < 1.1);
    CHECK(jsonAt(report, "/self_check/surfaces/1/thinnest_wall_at").size() == 3);
    CHECK_FALSE(jsonAt(report, "/self_check/surfaces/0").contains("thinnest_wall"));
    CHECK(r.out.find("comes within") == std::string::npos);
    // Every mesh was cleaned (no float32-degenerate triangle left) and measured against its level set.
    for (const char* m : {"/meshes/0", "/meshes/1"}) {
      CAPTURE(m);
      CHECK(jsonAt(report, std::string(m) + "/cleaning/applied") == true);
      CHECK(jsonAt(report, std::string(m) + "/cleaning/float32_degenerate_after") == 0);
      CHECK(jsonAt(report, std::string(m) + "/simplification/applied") == false);
      CHECK(testing::jsonNumber(report, std::string(m) + "/level_set_deviation/max_relative") < 1e-3);
    }

    const CliRun m = cli("mesh " + (out / "field.dpxf").string() + " --iso 0.05 -o " + (dir / "half.obj").string() +
                         " --quiet --json");
    CHECK(m.status == 0);
    CHECK(analyzeTopology(readMesh((dir / "half.obj").string())).components == 1);
    // An offset level drops what fit drops from its offset meshes (0.001 of the area) unless told otherwise;
    // the zero level keeps everything, as in fit.
    const Json half = Json::parse(m.out);
    CHECK(jsonAt(half, "/dropped/min_area_fraction").get<double>() == doctest::Approx(0.001));
    CHECK(jsonAt(report, "/self_check/surfaces/1/dropped/min_area_fraction").get<double>() == doctest::Approx(0.001));
    CHECK(jsonAt(report, "/self_check/surfaces/0/dropped/min_area_fraction").get<double>() == 0.0);
    const CliRun mc = cli("mesh " + (out / "field.dpxf").string() + " --min-component 0.01 -o " + (dir / "min.obj").string() +
                          " --quiet --json");
    CHECK(mc.status == 0);
    CHECK(analyzeTopology(readMesh((dir / "min.obj").string())).components == 1);
    CHECK(jsonAt(Json::parse(mc.out), "/dropped/min_area_fraction").get<double>() == doctest::Approx(0.01));
    // A triangle budget: meshoptimizer, or a clear error in a build without it.
    const CliRun small = cli("mesh " + (out / "field.dpxf").string() + " --max-triangles 500 -o " +
                             (dir / "small.stl").string() + " --quiet");
    if (simplificationAvailable()) {
      CHECK(small.status == 0);
      const MeshTopology st = analyzeTopology(readMesh((dir / "small.stl").string()));
      CHECK(st.faces <= 500);
      CHECK(st.watertight());
      CHECK(st.manifold());
      const CliRun checked = cli("check " + (dir / "small.stl").string() + " --strict --quiet");
      CHECK(checked.status == 0);
    } else {
      CHECK(small.status == 1);
      CHECK(small.err.find("meshoptimizer") != std::string::npos);
    }

    // The robust-field mechanisms are counted per level and can be switched off.
    for (const Json& level : levels) {
      CHECK(jsonAt(level, "/anchors").is_object());
      CHECK(jsonAt(level, "/offset_medial").is_array());
    }
    const CliRun plain = cli("fit " + input.string() + " --offset 0.1 --no-anchors --no-medial -o " + (dir / "plain").string() +
                             " --quiet --resolution 32 --evaluate-centres");
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
    // The projection predicts most face centres by default; --evaluate-centres evaluates every one.
    CHECK(testing::jsonNumber(report, "/meshes/0/projection/centres_predicted") > 0);
    CHECK(jsonAt(plainReport, "/meshes/0/projection/centres_predicted") == 0);
    CHECK(testing::jsonNumber(plainReport, "/meshes/0/projection/centres_evaluated") >=
          testing::jsonNumber(plainReport, "/meshes/0/topology/faces") * 0.9);

    const CliRun rel = cli("fit " + input.string() + " --offset-rel 0.1,-0.05 -o " + (dir / "rel").string() + " --quiet --format stl");
    CHECK(rel.status == 0);
    CHECK(fs::exists(dir / "rel" / "offset2.stl"));
    // Written in float32, every mesh still passes the strict check (no collapsed or zero-area triangle).
    for (const char* f : {"zero.stl", "offset1.stl", "offset2.stl"}) {
      const CliRun checked = cli("check " + (dir / "rel" / f).string() + " --strict --quiet");
      CAPTURE(f);
      CHECK(checked.status == 0);
    }
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

  TEST_CASE("cli: behaves like a CLI: command list, --help of every command, suggestions, -o, --json") {
    DUPLEXFIT_REQUIRE_CLI();
    const std::vector<std::string> commands{"fit", "mesh", "slice", "section", "check", "measure",
                                            "denoise", "normals", "solve", "devices"};
    // Bare duplexfit lists every command (usage status 1); --help too (status 0).
    const CliRun bare = cli("");
    CHECK(bare.status == 1);
    const CliRun help = cli("--help");
    CHECK(help.status == 0);
    for (const std::string& c : commands) {
      CAPTURE(c);
      CHECK(bare.err.find("  " + c + " ") != std::string::npos);
      CHECK(help.out.find("  " + c + " ") != std::string::npos);
      // Every command answers --help and -h with its own options, status 0, nothing on stderr.
      for (const char* flag : {"--help", "-h"}) {
        const CliRun h = cli(c + " " + flag);
        CHECK(h.status == 0);
        CHECK(h.out.find("Usage: " + c) != std::string::npos);
        CHECK(h.out.find("--help") != std::string::npos);
        CHECK(h.err.empty());
      }
    }
    const CliRun version = cli("--version");
    CHECK(version.status == 0);
    CHECK(version.out.rfind("duplexfit ", 0) == 0);
    // Typos: the nearest option or command is suggested.
    const fs::path dir = scratch("behaves");
    const fs::path input = sphereCloud(dir);
    const CliRun typo = cli("fit " + input.string() + " --ofset 0.1 -o " + (dir / "typo").string());
    CHECK(typo.status == 1);
    CHECK(typo.err.find("unknown option --ofset (did you mean --offset?)") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "typo"));
    const CliRun command = cli("mehs x.dpxf");
    CHECK(command.status == 1);
    CHECK(command.err.find("did you mean mesh?") != std::string::npos);
    const CliRun far = cli("fit " + input.string() + " --completely-unknown 1");
    CHECK(far.err.find("unknown option --completely-unknown") != std::string::npos);
    CHECK(far.err.find("did you mean") == std::string::npos);
    // One spelling: the normal estimation's neighbours are --normals-k in every command.
    for (const char* c : {"fit", "normals", "denoise"}) {
      CAPTURE(c);
      CHECK(cli(std::string(c) + " --help").out.find("--normals-k") != std::string::npos);
    }
    // fit -o names a folder: a file-like name is refused before any work, nothing is created.
    const CliRun file = cli("fit " + input.string() + " --offset 0.1 -o " + (dir / "out.ply").string() + " --quiet");
    CHECK(file.status == 1);
    CHECK(file.err.find("looks like a file name") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "out.ply"));
    // --offset-rel takes the fractions; with --offset too it is a usage error.
    CHECK(cli("fit " + input.string() + " --offset 0.1 --offset-rel 0.1 -o " + (dir / "both").string()).status == 1);
    CHECK_FALSE(fs::exists(dir / "both"));
    // fit --json prints report.json exactly as committed.
    const fs::path out = dir / "json";
    const CliRun json = cli("fit " + input.string() + " --offset-rel 0.1 -o " + out.string() + " --json --quiet");
    REQUIRE(json.status == 0);
    CHECK(json.out == readBytes(out / "report.json"));
    const Json report = testing::parseJson(json.out);
    REQUIRE(jsonAt(report, "/offsets").size() == 1);
    CHECK(jsonAt(report, "/offsets")[0].get<double>() == doctest::Approx(0.1).epsilon(0.02));  // side ≈ 1
    // The CG report says which tolerance the true residual met; "converged" only when one was.
    for (const Json& level : jsonAt(report, "/level_reports")) {
      const Json& cg = level.at("cg");
      const std::string met = cg.at("met").get<std::string>();
      if (cg.at("converged").get<bool>()) {
        CHECK((met == "relative" || met == "absolute"));
        if (met == "relative") CHECK(cg.at("relative_residual").get<double>() <= cg.at("tolerance").get<double>());
        if (met == "absolute") CHECK(cg.at("max_residual").get<double>() <= cg.at("absolute_tolerance").get<double>());
      } else {
        CHECK(met == "none");
      }
    }
    // mesh and section create a missing output folder as fit and slice do; a failed run leaves none.
    const fs::path nested = dir / "new" / "sub" / "zero.ply";
    const CliRun mesh = cli("mesh " + (out / "field.dpxf").string() + " --iso 0 -o " + nested.string() + " --quiet");
    CHECK(mesh.status == 0);
    CHECK(fs::exists(nested));
    const CliRun meshJson = cli("mesh " + (out / "field.dpxf").string() + " --iso 0 -o " + (dir / "m.ply").string() + " --json --quiet");
    REQUIRE(meshJson.status == 0);
    const Json meshReport = testing::parseJson(meshJson.out);
    CHECK(jsonAt(meshReport, "/topology/watertight").get<bool>());
    CHECK(jsonAt(meshReport, "/level_set_deviation/samples").get<std::size_t>() > 0);
    CHECK(jsonAt(meshReport, "/topology/faces").get<std::size_t>() == readMesh((dir / "m.ply").string()).faces.rows());
    // The neck pass is reported (and, with --no-neck-pass, not run).
    CHECK(jsonAt(meshReport, "/neck_pass/applied").is_boolean());
    const CliRun noNeck = cli("mesh " + (out / "field.dpxf").string() + " --iso 0 --no-neck-pass -o " +
                              (dir / "m2.ply").string() + " --json --quiet");
    REQUIRE(noNeck.status == 0);
    CHECK(jsonAt(testing::parseJson(noNeck.out), "/neck_pass/applied") == false);
    CHECK(jsonAt(testing::parseJson(noNeck.out), "/neck_pass/too_many_cells") == false);
    const fs::path picture = dir / "pictures" / "z.png";
    CHECK(cli("section " + (out / "field.dpxf").string() + " --plane z=0 --size 64 -o " + picture.string() + " --quiet").status == 0);
    CHECK(fs::exists(picture));
    const fs::path failed = dir / "never" / "m.ply";
    CHECK(cli("mesh " + (dir / "missing.dpxf").string() + " -o " + failed.string() + " --quiet").status == 2);
    CHECK_FALSE(fs::exists(dir / "never"));
  }
}
