// Slice outputs: the CLI file parses back to the same loops, malformed CLI files are clear errors, the
// PNG masks' white area matches the region's area, the SVG has one group per layer; and the `duplexfit
// slice` command: outputs, round trip and bad input without partial output.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "cli_runner.hpp"
#include "duplexfit/error.hpp"
#include "json_report.hpp"
#include "slice_checks.hpp"
#include "slice_fixtures.hpp"
#include "temp_dir.hpp"

using namespace duplexfit;
using namespace duplexfit::slicetest;
namespace fs = std::filesystem;

namespace {

fs::path scratch(const std::string& name) { return testing::scratchDir("duplexfit-slice-test", name); }

std::string readText(const fs::path& p) { return testing::readFile(p); }

void writeText(const fs::path& p, const std::string& text) { REQUIRE(testing::writeFile(p, text)); }

// The result's loops and the CLI file's polylines agree (heights, orientation flags, points). $$LAYER is
// the layer's top (CLI 2.0), and the reader's bottom is the previous layer's top.
void expectSameLoops(const SliceResult& r, const CliFile& f, double tol) {
  REQUIRE(f.layers.size() == r.layers.size());
  for (std::size_t i = 0; i < r.layers.size(); ++i) {
    CAPTURE(i);
    const SliceLayer& l = r.layers[i];
    CHECK(std::abs(f.layers[i].height - (l.height + l.thickness)) <= tol);
    if (i > 0) CHECK(f.layers[i].bottom == f.layers[i - 1].height);
    REQUIRE(f.layers[i].polylines.size() == l.loops.size());
    for (std::size_t k = 0; k < l.loops.size(); ++k) {
      const CliPolyline& p = f.layers[i].polylines[k];
      CHECK(p.closed);
      CHECK(p.dir == (l.loops[k].outer() ? 1 : 0));
      REQUIRE(p.points.rows() == l.loops[k].points.rows());
      CHECK((p.points - l.loops[k].points).cwiseAbs().maxCoeff() <= tol);
    }
  }
}

}  // namespace

TEST_SUITE("slice") {
  TEST_CASE("slice: the CLI file parses back to the same loops; bad CLI files are clear errors") {
    const fs::path dir = scratch("cli-file");
    const SliceResult& r = fittedSlice(SliceMode::Shell, 2);
    writeCli((dir / "a.cli").string(), r);
    const CliFile f = readCli((dir / "a.cli").string());
    CHECK(f.units == 1.0);
    CHECK(f.version == 200);
    CHECK(f.declaredLayers == static_cast<long>(r.layers.size()));
    expectSameLoops(r, f, 1e-6);
    // Units: 0.5 mm per file unit doubles the numbers in the file, and the reader scales them back.
    writeCli((dir / "b.cli").string(), r, 0.5);
    expectSameLoops(r, readCli((dir / "b.cli").string()), 1e-6);
    const std::string text = readText(dir / "b.cli");
    CHECK(text.find("$$UNITS/0.5000000") != std::string::npos);
    CHECK(text.rfind("$$HEADERSTART\n$$ASCII\n", 0) == 0);
    CHECK(text.find("$$GEOMETRYEND") != std::string::npos);
    CHECK_THROWS_AS(writeCli((dir / "c.cli").string(), r, 0.0), InvalidArgument);
    CHECK_FALSE(fs::exists(dir / "c.cli"));

    auto expectError = [&](const std::string& content, const char* part) {
      writeText(dir / "bad.cli", content);
      try {
        (void)readCli((dir / "bad.cli").string());
        FAIL("expected IoError mentioning " << part);
      } catch (const IoError& e) {
        const std::string m = e.what();
        CHECK_MESSAGE(m.find("bad.cli") != std::string::npos, m);
        CHECK_MESSAGE(m.find(part) != std::string::npos, m);
      }
    };
    const std::string head = "$$HEADERSTART\n$$ASCII\n$$UNITS/1\n$$LAYERS/1\n$$HEADEREND\n$$GEOMETRYSTART\n";
    expectError("", "empty");
    expectError("solid x\n", "not a CLI file");
    expectError("$$HEADERSTART\n$$BINARY\n", "binary");
    expectError(head + "$$LAYER/0.1\n$$POLYLINE/1,1,3,0,0,1,0\n$$GEOMETRYEND\n", ":8:");  // 3 points declared, 2 given
    expectError(head + "$$LAYER/0.1\n$$POLYLINE/1,1,2,0,0,1,x\n$$GEOMETRYEND\n", "not a number");
    expectError(head + "$$POLYLINE/1,1,1,0,0\n$$GEOMETRYEND\n", "before the first $$LAYER");
    expectError(head + "$$LAYER/0.1\n", "truncated");
    expectError(head + "$$GEOMETRYEND\n", "declares 1 layers");
    expectError(head + "$$LAYER/0.2\n$$LAYER/0.1\n$$GEOMETRYEND\n", "decrease");
    expectError("$$HEADERSTART\n$$UNITS/-1\n", "$$UNITS");
    CHECK_THROWS_AS(readCli((dir / "missing.cli").string()), IoError);
    // Comments and an open polyline are read.
    writeText(dir / "ok.cli", "$$HEADERSTART // made by hand //\n$$ASCII\n$$UNITS/2\n$$HEADEREND\n$$GEOMETRYSTART\n"
                              "$$LAYER/1\n$$POLYLINE/7,2,2,0,0,1,1\n$$GEOMETRYEND\n");
    const CliFile ok = readCli((dir / "ok.cli").string());
    REQUIRE(ok.layers.size() == 1);
    CHECK(ok.layers[0].height == 2.0);
    CHECK(ok.layers[0].bottom == 0.0);  // the first layer starts on the plate
    CHECK(ok.layers[0].thickness() == 2.0);
    CHECK_FALSE(ok.layers[0].polylines[0].closed);
    CHECK(ok.layers[0].polylines[0].id == 7);
    CHECK(ok.layers[0].polylines[0].points(1, 0) == 2.0);
  }

  TEST_CASE("slice: masks cover the region's area; the SVG has a group per layer") {
    const SliceResult& r = fittedSlice(SliceMode::Shell, 1);  // flat torus: rings with holes
    const Eigen::AlignedBox2d box = planeBox(r);
    const double px = 0.004;
    for (std::size_t i = 0; i < r.layers.size(); i += 3) {
      const SliceLayer& l = r.layers[i];
      const Image img = rasterizeLayer(l, box, px);
      std::size_t white = 0;
      for (std::uint8_t p : img.pixels) {
        CHECK((p == 0 || p == 255));
        white += p != 0 ? 1 : 0;
      }
      double perimeter = 0.0;
      for (const SliceLoop& loop : l.loops) {
        for (Eigen::Index k = 0; k < loop.points.rows(); ++k) perimeter += (pt(loop.points, k) - pt(loop.points, k + 1)).norm();
      }
      CAPTURE(i);
      // Pixel centres decide: the error is at most about half a pixel along the boundary.
      CHECK(std::abs(static_cast<double>(white) * px * px - l.area) <= 0.5 * perimeter * px + 4 * px * px);
    }
    // Row 0 is the top (largest v): a layer's loops all lie in the box and the image is not mirrored.
    SliceLayer tri;
    SliceLoop t;
    t.points.resize(3, 2);
    t.points << 0.0, 0.0, 1.0, 0.0, 0.0, 1.0;  // lower-left triangle, counter-clockwise
    t.area = 0.5;
    tri.loops.push_back(t);
    tri.area = 0.5;
    const Image timg = rasterizeLayer(tri, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1)), 0.1);
    CHECK(timg.width == 10);
    CHECK(*timg.at(0, 9) == 255);  // bottom-left
    CHECK(*timg.at(9, 0) == 0);    // top-right
    CHECK_THROWS_AS(rasterizeLayer(tri, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1)), 0.0), InvalidArgument);
    CHECK_THROWS_AS(rasterizeLayer(tri, Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 1)), 1e-6), InvalidArgument);

    const fs::path dir = scratch("svg");
    writeSliceSvg((dir / "s.svg").string(), r);
    const std::string svg = readText(dir / "s.svg");
    std::size_t groups = 0;
    for (std::size_t at = svg.find("<g id=\"layer_"); at != std::string::npos; at = svg.find("<g id=\"layer_", at + 1)) ++groups;
    CHECK(groups == r.layers.size());
    writeSliceSvg((dir / "one.svg").string(), r, 2);
    CHECK(readText(dir / "one.svg").find("layer_00003") != std::string::npos);
    CHECK_THROWS_AS(writeSliceSvg((dir / "no.svg").string(), r, 9999), InvalidArgument);
  }

  TEST_CASE("slice: the command writes the CLI file, SVG, JSON and masks; bad input leaves nothing") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path dir = scratch("cmd");
    const fs::path field = dir / "torus.dpxf";
    fittedUprightTorus().save(field.string());
    const std::string spec = sliceDevice().info().spec;
    auto run = [&](const std::string& args, std::string* err = nullptr) {
      const testing::CliRun r = testing::runCli("slice " + args);
      if (err) *err = r.err;
      return r.status;
    };
    const fs::path out = dir / "out";
    std::string err;
    REQUIRE(run(field.string() + " --cusp 0.01 --min-layer 0.0025 --max-layer 0.05 --grid 0.01 --mode shell --png-xy 0.01 "
                "--device " + spec + " -o " + out.string(), &err) == 0);
    CHECK(err.find("layer 1 ") != std::string::npos);  // progress on stderr
    for (const char* name : {"slices.cli", "slices.svg", "slices.json", "masks/layer_00001.png"}) {
      CHECK_MESSAGE(fs::exists(out / name), name);
    }
    // The file holds exactly what the library computes with the same options and device, placed on the
    // plate by default (the plate a whole number of mask pixels).
    const SliceResult& r = fittedSlice(SliceMode::Shell, 2);
    PlacementOptions place;
    place.plateStep = 0.01;
    const SliceResult placed = applyPlacement(r, placeSlices(r, place));
    const CliFile f = readCli((out / "slices.cli").string());
    expectSameLoops(placed, f, 1e-6);
    std::size_t masks = 0;
    for (const auto& e : fs::directory_iterator(out / "masks")) masks += e.path().extension() == ".png" ? 1 : 0;
    CHECK(masks == r.layers.size());
    const Image m = readPng((out / "masks/layer_00040.png").string());
    std::size_t white = 0;
    for (std::uint8_t p : m.pixels) white += p != 0 ? 1 : 0;
    CHECK(static_cast<double>(white) * 1e-4 == doctest::Approx(r.layers[39].area).epsilon(0.1));
    const testing::Json json = testing::readJsonFile(out / "slices.json");
    CHECK(testing::jsonAt(json, "/layer_count") == r.layers.size());
    CHECK(testing::jsonAt(json, "/mode") == "shell");
    CHECK(testing::jsonAt(json, "/heights").size() == r.layers.size());
    CHECK(testing::jsonAt(json, "/thickness").is_object());
    CHECK(testing::jsonAt(json, "/loops").is_number());
    CHECK(testing::jsonAt(json, "/seconds").is_object());
    const testing::Json layers = testing::jsonAt(json, "/layers");
    CHECK(layers.size() == r.layers.size());
    for (const testing::Json& layer : layers) {
      CHECK(testing::jsonAt(layer, "/area").is_number());
      CHECK(testing::jsonAt(layer, "/thickness").is_number());
      CHECK(testing::jsonAt(layer, "/loops").is_number());
    }
    // Uniform layers along x with per-layer SVGs.
    const fs::path out2 = dir / "out2";
    REQUIRE(run(field.string() + " --layer 0.25 --axis x --svg-per-layer --quiet --device " + spec + " -o " + out2.string()) == 0);
    CHECK(readCli((out2 / "slices.cli").string()).layers.size() == 4);
    CHECK(fs::exists(out2 / "svg/layer_00004.svg"));

    // Bad input: a clear message, a non-zero status and nothing in the output folder.
    const fs::path bad = dir / "bad";
    writeText(dir / "corrupt.dpxf", "DPXF garbage that is not a field");
    const struct {
      std::string args;
      const char* part;
    } cases[] = {
        {field.string() + " --cusp 0", "--cusp"},
        {field.string() + " --cusp -0.01", "--cusp"},
        {field.string() + " --cusp 0.01 --min-layer 0.1 --max-layer 0.05", "--min-layer"},
        {field.string() + " --cusp 0.01 --min-layer 0.1", "minimum layer"},
        {field.string() + " --cusp 0.01 --axis w", "axis 'w'"},
        {field.string() + " --cusp 0.01 --grid 0", "--grid"},
        {field.string() + " --cusp 0.01 --grid -1", "--grid"},
        {field.string() + " --cusp 0.01 --mode solid", "solid"},
        {field.string(), "--cusp"},
        {field.string() + " --cusp 0.01 --mode shell --offset-index 3", "offsetIndex"},
        {field.string() + " --cusp 0.01 --png-xy 1e-7", "--png-xy"},
        {field.string() + " --cusp 0.01 --bogus", "--bogus"},
        {(dir / "corrupt.dpxf").string() + " --cusp 0.01", "corrupt.dpxf"},
        {(dir / "missing.dpxf").string() + " --cusp 0.01", "missing.dpxf"},
    };
    for (const auto& c : cases) {
      CAPTURE(c.args);
      fs::remove_all(bad);
      fs::create_directories(bad);
      const int status = run(c.args + " --quiet -o " + bad.string(), &err);
      CHECK(status != 0);
      CHECK_MESSAGE(err.find(c.part) != std::string::npos, err);
      CHECK(fs::is_empty(bad));
    }
  }
}
