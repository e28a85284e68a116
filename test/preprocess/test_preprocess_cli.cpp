// `duplexfit denoise` and `duplexfit normals` run as a user would: outputs, JSON summaries, and bad input
// that must fail with a clear message, a non-zero status and no output file.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_runner.hpp"
#include "duplexfit/io.hpp"
#include "json_report.hpp"
#include "preprocess/preprocess_test_util.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using namespace duplexfit;

namespace {

using testing::CliRun;
using testing::jsonAt;
using testing::jsonNumber;

/// A temporary folder for one test case; cli() runs the duplexfit command.
class Scratch {
 public:
  fs::path operator/(const std::string& name) const { return dir_ / name; }
  CliRun cli(const std::string& args) const { return testing::runCli(args); }

 private:
  testing::TempDir dir_{"duplexfit-preprocess-cli"};
};

void writeXyz(const fs::path& p, const Points& x) {
  std::ofstream out(p);
  out.precision(17);
  for (Eigen::Index i = 0; i < x.rows(); ++i) out << x(i, 0) << " " << x(i, 1) << " " << x(i, 2) << "\n";
}

}  // namespace

TEST_SUITE("preprocess") {

TEST_CASE("cli: denoise writes a filtered cloud and a JSON summary") {
  DUPLEXFIT_REQUIRE_CLI();
  const Scratch s;
  const PointSet noisy = testing::noisySphere(3000, 0.5, 0.005);
  writePointCloud((s / "noisy.ply").string(), noisy);
  const CliRun r = s.cli("denoise " + (s / "noisy.ply").string() + " -o " + (s / "out.ply").string() +
                         " --device ref --json --quiet --iterations 2 --sigma-r 0.02");
  INFO(r.err);
  REQUIRE(r.status == 0);
  const testing::Json j = testing::parseJson(r.out);
  CHECK(jsonAt(j, "/command") == "denoise");
  CHECK(jsonNumber(j, "/sigma_range") == doctest::Approx(0.02));
  CHECK(jsonAt(j, "/iterations") == 2);
  CHECK(jsonAt(j, "/seconds/filter").is_number());
  const PointSet out = readPointCloud((s / "out.ply").string());
  REQUIRE(out.size() == noisy.size());
  // Sparse sampling (3000 points) makes the outward bias of the tangent-plane projections large; the spread
  // about the mean radius shows the smoothing.
  const testing::RadialError e = testing::radialError(out.positions(), 0.5);
  CHECK(std::sqrt(e.rms * e.rms - e.mean * e.mean) < 0.5 * testing::radialError(noisy.positions(), 0.5).rms);
}

TEST_CASE("cli: normals of a cloud without normals") {
  DUPLEXFIT_REQUIRE_CLI();
  const Scratch s;
  Points truth;
  const Points x = testing::fibonacciSphere(2000, 0.5, &truth);
  writeXyz(s / "bare.xyz", x);
  const CliRun r = s.cli("normals " + (s / "bare.xyz").string() + " -o " + (s / "n.ply").string() +
                         " --device ref --normals-k 12 --json --quiet");
  INFO(r.err);
  REQUIRE(r.status == 0);
  const testing::Json j = testing::parseJson(r.out);
  CHECK(jsonAt(j, "/k") == 12);
  CHECK(jsonAt(j, "/input_had_normals") == false);
  CHECK(jsonAt(j, "/components") == 1);
  const PointSet out = readPointCloud((s / "n.ply").string());
  REQUIRE(out.size() == 2000);
  for (Eigen::Index i = 0; i < out.normals().rows(); ++i) CHECK(out.normals().row(i).dot(truth.row(i)) > 0.99);

  // --keep-existing copies a cloud's own normals; without it they are re-estimated and compared.
  const CliRun keep = s.cli("normals " + (s / "n.ply").string() + " -o " + (s / "k.ply").string() +
                            " --device ref --keep-existing --json --quiet");
  REQUIRE(keep.status == 0);
  CHECK(jsonAt(testing::parseJson(keep.out), "/kept_existing") == true);
  const CliRun again = s.cli("normals " + (s / "n.ply").string() + " -o " + (s / "k.ply").string() +
                             " --device ref --json --quiet");
  REQUIRE(again.status == 0);
  CHECK(jsonAt(testing::parseJson(again.out), "/agree_with_input_normals") == 1);
}

TEST_CASE("cli: preprocess errors leave no output") {
  DUPLEXFIT_REQUIRE_CLI();
  const Scratch s;
  Points truth;
  writeXyz(s / "bare.xyz", testing::fibonacciSphere(500, 0.5, &truth));
  Points plane(100, 3);
  for (Eigen::Index i = 0; i < 100; ++i) plane.row(i) << 0.1 * static_cast<double>(i % 10), 0.1 * static_cast<double>(i / 10), 0.0;
  writeXyz(s / "plane.xyz", plane);
  const std::string out = (s / "o.ply").string();

  CliRun r = s.cli("denoise " + (s / "bare.xyz").string() + " -o " + out + " --device ref");
  CHECK(r.status == 1);
  CHECK(r.err.find("bare.xyz") != std::string::npos);
  CHECK(r.err.find("no normals") != std::string::npos);
  r = s.cli("normals " + (s / "plane.xyz").string() + " -o " + out + " --device ref");
  CHECK(r.status == 1);
  CHECK(r.err.find("plane.xyz") != std::string::npos);
  CHECK(r.err.find("plane") != std::string::npos);
  r = s.cli("normals " + (s / "bare.xyz").string() + " -o " + out + " --device ref --normals-k 600");
  CHECK(r.status == 1);
  CHECK(r.err.find("at least 601") != std::string::npos);
  r = s.cli("normals " + (s / "missing.xyz").string() + " -o " + out + " --device ref");
  CHECK(r.status == 2);
  r = s.cli("normals " + (s / "bare.xyz").string() + " --device ref");
  CHECK(r.status == 1);
  CHECK(r.err.find("-o OUT") != std::string::npos);
  r = s.cli("denoise " + (s / "bare.xyz").string() + " -o " + out + " --iterations 0");
  CHECK(r.status == 1);
  r = s.cli("normals " + (s / "bare.xyz").string() + " -o " + out + " --bogus");
  CHECK(r.status == 1);
  CHECK(r.err.find("unknown option --bogus") != std::string::npos);
  CHECK_FALSE(fs::exists(out));
  // Flat input is accepted on request, with consistent (not outward) normals.
  r = s.cli("normals " + (s / "plane.xyz").string() + " -o " + out + " --device ref --allow-unoriented --json");
  CHECK(r.status == 0);
  CHECK(jsonAt(testing::parseJson(r.out), "/ambiguous_components") == 1);
  CHECK(fs::exists(out));
}

}  // TEST_SUITE
