// Slices on the build plate: placement (lowest layer's bottom at z = 0, the part centred on the plate),
// scale and output units, $$LAYER as the layer's top, and PNG masks of the whole plate with their
// resolution. The files are read back with readers written here from the formats' specifications (CLI
// 2.0 ASCII; PNG: signature, chunks with CRC-32, IHDR, pHYs), not with the library's readers.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/image.hpp"
#include "json_report.hpp"
#include "slice_fixtures.hpp"
#include "temp_dir.hpp"

using namespace duplexfit;
using namespace duplexfit::slicetest;
namespace fs = std::filesystem;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---- CLI 2.0 ASCII, from the specification -------------------------------------------------------
// Lines "$$COMMAND/p1,p2,..." ("//" starts a comment); the header between $$HEADERSTART and $$HEADEREND
// ($$UNITS/u: u mm per coordinate unit; $$LAYERS/n), the geometry between $$GEOMETRYSTART and
// $$GEOMETRYEND: "$$LAYER/z" starts a layer whose upper boundary is at z, "$$POLYLINE/id,dir,n,x1,y1,...".
struct RawCli {
  double units = kNaN;
  long layersDeclared = -1;
  bool ended = false;
  std::vector<double> z;                             // per layer, in file units
  std::vector<std::vector<std::vector<double>>> xy;  // per layer, per polyline: x1, y1, x2, y2, ...
  std::vector<std::string> header;                   // the header's lines
};

std::vector<double> numbers(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const double d = std::strtod(item.c_str(), &end);
    REQUIRE_MESSAGE((end != item.c_str() && *end == '\0'), "not a number: '" << item << "'");
    v.push_back(d);
  }
  return v;
}

RawCli parseCliText(const std::string& text) {
  RawCli f;
  std::istringstream in(text);
  std::string line;
  bool header = false, geometry = false;
  while (std::getline(in, line)) {
    const auto comment = line.find("//");
    if (comment != std::string::npos) line.erase(comment);
    while (!line.empty() && (line.back() == ' ' || line.back() == '\r')) line.pop_back();
    if (line.empty()) continue;
    const auto slash = line.find('/');
    const std::string cmd = line.substr(0, slash), args = slash == std::string::npos ? "" : line.substr(slash + 1);
    if (cmd == "$$HEADERSTART") {
      header = true;
    } else if (cmd == "$$HEADEREND") {
      header = false;
    } else if (header) {
      f.header.push_back(line);
      if (cmd == "$$UNITS") f.units = numbers(args).at(0);
      if (cmd == "$$LAYERS") f.layersDeclared = static_cast<long>(numbers(args).at(0));
    } else if (cmd == "$$GEOMETRYSTART") {
      geometry = true;
    } else if (cmd == "$$GEOMETRYEND") {
      geometry = false;
      f.ended = true;
    } else if (geometry && cmd == "$$LAYER") {
      f.z.push_back(numbers(args).at(0));
      f.xy.emplace_back();
    } else if (geometry && cmd == "$$POLYLINE") {
      REQUIRE(!f.z.empty());
      const std::vector<double> v = numbers(args);
      REQUIRE(v.size() >= 3);
      REQUIRE(v.size() == 3 + 2 * static_cast<std::size_t>(v[2]));
      f.xy.back().emplace_back(v.begin() + 3, v.end());
    } else {
      FAIL("unexpected CLI line: " << line);
    }
  }
  return f;
}

// ---- PNG, from the specification -------------------------------------------------------------------
// An 8-byte signature, then chunks: 4-byte big-endian length, 4-byte type, data, CRC-32 (ISO 3309,
// reflected polynomial 0xEDB88320) over type and data. IHDR first: width, height (4 bytes each), bit depth,
// colour type, ...; pHYs: pixels per unit x, y (4 bytes each), unit (1 = metre).
struct RawPng {
  bool signature = false, crcOk = true, ihdrFirst = false, hasPhys = false;
  std::uint32_t width = 0, height = 0, physX = 0, physY = 0;
  int bitDepth = 0, colourType = -1, physUnit = -1;
  std::vector<std::string> chunks;
};

std::uint32_t be32(const std::string& b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

std::uint32_t crc32(const std::string& bytes, std::size_t at, std::size_t n) {
  std::uint32_t c = 0xffffffffu;
  for (std::size_t i = at; i < at + n; ++i) {
    c ^= static_cast<unsigned char>(bytes[i]);
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? (c >> 1) ^ 0xedb88320u : c >> 1;
  }
  return c ^ 0xffffffffu;
}

RawPng parsePngChunks(const std::string& b) {
  RawPng p;
  static const char sig[8] = {'\x89', 'P', 'N', 'G', '\r', '\n', '\x1a', '\n'};
  p.signature = b.size() >= 8 && std::equal(sig, sig + 8, b.begin());
  std::size_t at = 8;
  while (p.signature && at + 12 <= b.size()) {
    const std::uint32_t length = be32(b, at);
    REQUIRE(at + 12 + length <= b.size());
    const std::string type = b.substr(at + 4, 4);
    const std::size_t data = at + 8;
    p.crcOk = p.crcOk && crc32(b, at + 4, 4 + length) == be32(b, data + length);
    if (p.chunks.empty()) p.ihdrFirst = type == "IHDR";
    p.chunks.push_back(type);
    if (type == "IHDR" && length == 13) {
      p.width = be32(b, data);
      p.height = be32(b, data + 4);
      p.bitDepth = static_cast<unsigned char>(b[data + 8]);
      p.colourType = static_cast<unsigned char>(b[data + 9]);
    } else if (type == "pHYs" && length == 9) {
      p.hasPhys = true;
      p.physX = be32(b, data);
      p.physY = be32(b, data + 4);
      p.physUnit = static_cast<unsigned char>(b[data + 8]);
    }
    at = data + length + 4;
    if (type == "IEND") break;
  }
  return p;
}

fs::path scratch(const std::string& name) { return testing::scratchDir("duplexfit-slice-plate-test", name); }

/// The fitted upright torus saved once per process (x in [−0.5, 0.5], y in [−0.2, 0.2], z in [−0.5, 0.5]).
const fs::path& torusField() {
  static const fs::path path = [] {
    const fs::path p = scratch("field") / "torus.dpxf";
    fittedUprightTorus().save(p.string());
    return p;
  }();
  return path;
}

testing::CliRun slice(const std::string& args, const fs::path& out) {
  return testing::runCli("slice " + torusField().string() + " " + args + " --device " + sliceDevice().info().spec +
                         " --quiet -o " + out.string());
}

/// Every polyline point of a CLI file (file units): the (x, y) extent over all layers.
Eigen::AlignedBox2d extentOf(const RawCli& f) {
  Eigen::AlignedBox2d box;
  for (const auto& layer : f.xy) {
    for (const auto& poly : layer) {
      for (std::size_t k = 0; k + 1 < poly.size(); k += 2) box.extend(Eigen::Vector2d(poly[k], poly[k + 1]));
    }
  }
  return box;
}

double num(const testing::Json& j, const std::string& pointer) { return testing::jsonNumber(j, pointer); }

}  // namespace

TEST_SUITE("slice") {
  TEST_CASE("slice: on the build plate: z from 0, $$LAYER = top, centred, full-plate masks with their DPI") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path out = scratch("plate");
    // Model units ×10 → mm on a 12 x 9 mm plate; the part is 10 x 4 x 10 mm. Pixel 0.05 mm: 240 x 180, 508 DPI.
    const testing::CliRun run = slice("--cusp 0.01 --min-layer 0.0025 --max-layer 0.05 --grid 0.01 --mode shell "
                                      "--scale 10 --units mm --plate 12x9 --png-xy 0.05 --svg", out);
    REQUIRE_MESSAGE(run.status == 0, run.err);
    const double scale = 10.0, grid = 0.01 * scale, pixel = 0.05, plateW = 12.0, plateD = 9.0;

    const RawCli cli = parseCliText(testing::readFile(out / "slices.cli"));
    CHECK(cli.ended);
    CHECK(cli.units == 1.0);
    REQUIRE(cli.z.size() > 10);
    CHECK(cli.layersDeclared == static_cast<long>(cli.z.size()));
    for (std::size_t i = 0; i < cli.z.size(); ++i) {
      CAPTURE(i);
      CHECK(cli.z[i] > 0.0);  // a reader that skips z <= 0 keeps every layer
      if (i > 0) CHECK(cli.z[i] > cli.z[i - 1]);
    }
    const Eigen::AlignedBox2d extent = extentOf(cli);
    CHECK(std::abs(extent.center().x() - 0.5 * plateW) <= pixel);
    CHECK(std::abs(extent.center().y() - 0.5 * plateD) <= pixel);
    CHECK(extent.sizes().x() == doctest::Approx(10.0).epsilon(0.01));  // the torus' width 1 model unit
    CHECK(extent.sizes().y() == doctest::Approx(4.0).epsilon(0.01));   // its tube's diameter 0.4

    const testing::Json json = testing::readJsonFile(out / "slices.json");
    const testing::Json layers = testing::jsonAt(json, "/layers");
    REQUIRE(layers.size() == cli.z.size());
    CHECK(num(layers[0], "/bottom") == 0.0);
    for (std::size_t i = 0; i < layers.size(); ++i) {
      CAPTURE(i);
      const double bottom = num(layers[i], "/bottom"), top = num(layers[i], "/top"), t = num(layers[i], "/thickness");
      CHECK(std::abs(top - cli.z[i]) <= 1e-6);  // $$LAYER is the top (7 decimals in the file)
      CHECK(top - bottom == doctest::Approx(t).epsilon(1e-9));
      CHECK((t >= 0.0025 * scale * (1 - 1e-9) && t <= 0.05 * scale * (1 + 1e-9)));
      if (i > 0) CHECK(std::abs(bottom - num(layers[i - 1], "/top")) <= 1e-9);
    }
    // The placement maps back: the solid's lowest point (the torus' bottom, model z = −0.5) lands on z = 0
    // within one grid step, and the part's centre (model x = y = 0) on the plate's centre.
    CHECK(testing::jsonAt(json, "/placement/place") == "plate");
    CHECK(testing::jsonAt(json, "/placement/units") == "mm");
    CHECK(num(json, "/placement/units_mm") == 1.0);
    CHECK(num(json, "/placement/scale") == scale);
    CHECK(num(json, "/placement/plate/0") == plateW);
    CHECK(num(json, "/placement/plate/1") == plateD);
    CHECK(testing::jsonAt(json, "/placement/plate_given") == true);
    CHECK(std::abs(scale * -0.5 + num(json, "/placement/translation/2")) <= grid);
    CHECK(std::abs(num(json, "/placement/translation/0") - 0.5 * plateW) <= grid);
    CHECK(std::abs(num(json, "/placement/translation/1") - 0.5 * plateD) <= grid);
    CHECK(num(json, "/placement/lowest_model") == doctest::Approx(-num(json, "/placement/translation/2") / scale));
    CHECK(num(json, "/placement/part_min/2") == 0.0);
    CHECK(num(json, "/placement/part_max/2") == doctest::Approx(cli.z.back()).epsilon(1e-7));

    // Every mask covers the whole plate at the pixel size, with its resolution in pHYs.
    const double ppm = 1000.0 / pixel;  // pixels per metre: the pixel is 0.05 mm
    CHECK(num(json, "/masks/pixel") == pixel);
    CHECK(num(json, "/masks/width_px") == 240);
    CHECK(num(json, "/masks/height_px") == 180);
    CHECK(num(json, "/masks/origin/0") == 0.0);     // pixel (0, 0)'s outer corner: the plate's (min x, max y)
    CHECK(num(json, "/masks/origin/1") == plateD);
    CHECK(num(json, "/masks/pixels_per_metre") == ppm);
    CHECK(num(json, "/masks/dpi") == doctest::Approx(25.4 / pixel));
    for (std::size_t i : {std::size_t{0}, layers.size() / 2, layers.size() - 1}) {
      CAPTURE(i);
      char name[32];
      std::snprintf(name, sizeof name, "masks/layer_%05zu.png", i + 1);
      const RawPng png = parsePngChunks(testing::readFile(out / name));
      CHECK(png.signature);
      CHECK(png.crcOk);
      CHECK(png.ihdrFirst);
      CHECK(png.width == static_cast<std::uint32_t>(std::lround(plateW / pixel)));
      CHECK(png.height == static_cast<std::uint32_t>(std::lround(plateD / pixel)));
      CHECK(png.bitDepth == 8);
      CHECK(png.colourType == 0);  // greyscale
      REQUIRE(png.hasPhys);
      CHECK(png.physUnit == 1);  // metre
      CHECK(png.physX == static_cast<std::uint32_t>(std::lround(ppm)));
      CHECK(png.physY == png.physX);
      CHECK(std::abs(png.physX * 0.0254 - 25.4 / pixel) <= 0.0254);  // DPI 508
      CHECK(png.chunks.back() == "IEND");
    }
    // The middle layer's white pixels, mapped through the recorded origin and pixel size, are centred on
    // the plate (the widest section of the torus) within a pixel, and their area matches the layer's.
    std::size_t mid = 0;
    for (std::size_t i = 0; i < layers.size(); ++i) {
      if (std::abs(num(layers[i], "/bottom") - 5.0) < std::abs(num(layers[mid], "/bottom") - 5.0)) mid = i;
    }
    char name[32];
    std::snprintf(name, sizeof name, "masks/layer_%05zu.png", mid + 1);
    const Image img = readPng((out / name).string());
    int c0 = img.width, c1 = -1, r0 = img.height, r1 = -1;
    std::size_t white = 0;
    for (int r = 0; r < img.height; ++r) {
      for (int c = 0; c < img.width; ++c) {
        if (*img.at(c, r) == 0) continue;
        ++white;
        c0 = std::min(c0, c), c1 = std::max(c1, c), r0 = std::min(r0, r), r1 = std::max(r1, r);
      }
    }
    REQUIRE(white > 0);
    const double ox = num(json, "/masks/origin/0"), oy = num(json, "/masks/origin/1");
    CHECK(std::abs(ox + 0.5 * (c0 + c1 + 1) * pixel - 0.5 * plateW) <= 1.5 * pixel);
    CHECK(std::abs(oy - 0.5 * (r0 + r1 + 1) * pixel - 0.5 * plateD) <= 1.5 * pixel);
    CHECK(static_cast<double>(white) * pixel * pixel == doctest::Approx(num(layers[mid], "/area")).epsilon(0.05));
  }

  TEST_CASE("slice: inches, a default plate of whole pixels, and --place none") {
    DUPLEXFIT_REQUIRE_CLI();
    // Model units ×0.1 → inches: $$UNITS is 25.4 (mm per unit), the numbers are inches; 0.002 in pixels.
    const fs::path out = scratch("inches");
    testing::CliRun run = slice("--layer 0.05 --grid 0.01 --scale 0.1 --units in --png-xy 0.002", out);
    REQUIRE_MESSAGE(run.status == 0, run.err);
    const RawCli cli = parseCliText(testing::readFile(out / "slices.cli"));
    CHECK(cli.units == 25.4);
    REQUIRE(cli.z.size() == 20);
    CHECK(cli.z.front() == doctest::Approx(0.005));  // the first uniform layer's top: 0.05 × 0.1 in
    for (double z : cli.z) CHECK(z > 0.0);
    const testing::Json json = testing::readJsonFile(out / "slices.json");
    const double w = num(json, "/placement/plate/0"), d = num(json, "/placement/plate/1"), px = 0.002;
    CHECK(testing::jsonAt(json, "/placement/plate_given") == false);
    CHECK(testing::jsonAt(json, "/placement/units") == "in");
    CHECK(num(json, "/placement/units_mm") == 25.4);
    // The automatic plate holds the part (0.1 x 0.04 in) with a margin and is a whole number of pixels.
    CHECK((w >= 0.1 && w <= 0.1 + 0.008));
    CHECK((d >= 0.04 && d <= 0.04 + 0.008));
    const Eigen::AlignedBox2d extent = extentOf(cli);
    CHECK(std::abs(extent.center().x() - 0.5 * w) <= px);
    CHECK(std::abs(extent.center().y() - 0.5 * d) <= px);
    const RawPng png = parsePngChunks(testing::readFile(out / "masks/layer_00010.png"));
    CHECK(png.crcOk);
    CHECK(std::abs(png.width * px - w) <= 1e-9);
    CHECK(std::abs(png.height * px - d) <= 1e-9);
    REQUIRE(png.hasPhys);
    CHECK(png.physUnit == 1);
    CHECK(png.physX == 19685);  // 1 / (0.002 × 0.0254 m), rounded: 500 DPI
    CHECK(num(json, "/masks/dpi") == doctest::Approx(500.0));
    // The library's reader gives millimetres.
    const CliFile f = readCli((out / "slices.cli").string());
    CHECK(f.layers.front().height == doctest::Approx(0.005 * 25.4));
    CHECK(f.layers.front().bottom == 0.0);

    // --place none keeps the model's coordinates (the first layer's top at −0.5 + 0.25).
    const fs::path none = scratch("none");
    run = slice("--layer 0.25 --place none", none);
    REQUIRE_MESSAGE(run.status == 0, run.err);
    const RawCli raw = parseCliText(testing::readFile(none / "slices.cli"));
    REQUIRE(raw.z.size() == 4);
    CHECK(raw.z.front() == doctest::Approx(-0.25).epsilon(1e-4));
    const testing::Json j = testing::readJsonFile(none / "slices.json");
    CHECK(testing::jsonAt(j, "/placement/place") == "none");
    for (int k = 0; k < 3; ++k) CHECK(num(j, "/placement/translation/" + std::to_string(k)) == 0.0);
    CHECK(std::abs(extentOf(raw).center().x()) <= 0.01);
  }

  TEST_CASE("slice: bad scale, units, plate and pixel size are option errors with no output") {
    DUPLEXFIT_REQUIRE_CLI();
    const fs::path bad = scratch("bad");
    const struct {
      std::string args;
      const char* part;
    } cases[] = {
        {"--layer 0.25 --scale -1", "--scale"},
        {"--layer 0.25 --scale 0", "--scale"},
        {"--layer 0.25 --png-xy 0", "--png-xy"},
        {"--layer 0.25 --png-xy -0.1", "--png-xy"},
        {"--layer 0.25 --units cm", "--units"},
        {"--layer 0.25 --units 25.4", "--units"},
        {"--layer 0.25 --place floor", "--place"},
        {"--layer 0.25 --plate 12", "--plate"},
        {"--layer 0.25 --plate 0x9", "--plate"},
        {"--layer 0.25 --plate 12x9 --place none", "--plate"},
        {"--layer 0.25 --scale 10 --plate 8x9", "--plate"},    // the part's box is larger: before slicing
        {"--layer 0.25 --scale 10 --plate 9.9x9", "--plate"},  // the loops are wider: after slicing
        {"--layer 0.25 --plate 12x9 --png-xy 1e-4", "--png-xy"},  // 120000 pixels a side
    };
    for (const auto& c : cases) {
      CAPTURE(c.args);
      fs::remove_all(bad);
      fs::create_directories(bad);
      const testing::CliRun run = slice(c.args, bad);
      CHECK(run.status == 1);  // an option error (cli/args.hpp kUsage), as the other bad options
      CHECK_MESSAGE(run.err.find(c.part) != std::string::npos, run.err);
      CHECK(fs::is_empty(bad));
    }
  }

  TEST_CASE("slice: placeSlices and applyPlacement (library)") {
    const SliceResult& r = fittedSlice(SliceMode::Shell, 2);
    PlacementOptions o;
    o.scale = 2.0;
    o.plate = Eigen::Vector2d(3.0, 2.0);
    const SlicePlacement p = placeSlices(r, o);
    const SliceResult q = applyPlacement(r, p);
    REQUIRE(q.layers.size() == r.layers.size());
    CHECK(q.layers.front().height == 0.0);
    CHECK(p.lowestModel == r.layers.front().height);
    CHECK(p.part.min().z() == 0.0);
    CHECK(p.part.max().z() == doctest::Approx(q.layers.back().height + q.layers.back().thickness));
    Eigen::AlignedBox2d extent;
    for (std::size_t i = 0; i < r.layers.size(); ++i) {
      CAPTURE(i);
      CHECK(q.layers[i].height == doctest::Approx(2.0 * r.layers[i].height + p.translation.z()));
      CHECK(q.layers[i].thickness == doctest::Approx(2.0 * r.layers[i].thickness));
      CHECK(q.layers[i].area == doctest::Approx(4.0 * r.layers[i].area));
      REQUIRE(q.layers[i].loops.size() == r.layers[i].loops.size());
      for (const SliceLoop& loop : q.layers[i].loops) {
        for (Eigen::Index k = 0; k < loop.points.rows(); ++k) {
          extent.extend(Eigen::Vector2d(loop.points(k, 0), loop.points(k, 1)));
        }
      }
    }
    CHECK(extent.center().x() == doctest::Approx(1.5));
    CHECK(extent.center().y() == doctest::Approx(1.0));
    CHECK(q.grid == doctest::Approx(2.0 * r.grid));
    CHECK(q.bounds.min().z() == 0.0);  // bounds: the placed part's box
    CHECK(q.bounds.max().x() == doctest::Approx(extent.max().x()));

    // Errors: too small a plate, a bad scale, a plate without plate placement.
    o.plate = Eigen::Vector2d(1.9, 2.0);
    CHECK_THROWS_AS((void)placeSlices(r, o), InvalidArgument);
    o.plate = Eigen::Vector2d(3.0, 2.0);
    o.scale = -1.0;
    CHECK_THROWS_AS((void)placeSlices(r, o), InvalidArgument);
    o.scale = 1.0;
    o.place = SlicePlace::None;
    CHECK_THROWS_AS((void)placeSlices(r, o), InvalidArgument);
    o.plate = Eigen::Vector2d::Zero();
    const SlicePlacement none = placeSlices(r, o);
    CHECK(none.translation == Eigen::Vector3d::Zero());
    CHECK(applyPlacement(r, none).layers[3].height == r.layers[3].height);

    CHECK(parseSlicePlace("plate") == SlicePlace::Plate);
    CHECK(parseSlicePlace("none") == SlicePlace::None);
    CHECK_THROWS_AS((void)parseSlicePlace("floor"), InvalidArgument);
    CHECK(lengthUnitMillimetres("mm") == 1.0);
    CHECK(lengthUnitMillimetres("in") == 25.4);
    CHECK(lengthUnitMillimetres("um") == 0.001);
    CHECK_THROWS_AS((void)lengthUnitMillimetres("cm"), InvalidArgument);
    CHECK(parsePlateSize("120x80") == Eigen::Vector2d(120.0, 80.0));
    CHECK(parsePlateSize("2.5,4") == Eigen::Vector2d(2.5, 4.0));
    for (const char* text : {"120", "0x80", "-1x5", "1x", "ax3", "1x2x3", "inf x 3"}) {
      CAPTURE(text);
      CHECK_THROWS_AS((void)parsePlateSize(text), InvalidArgument);
    }

    // Along x: the output's z is the model's x (the SliceResult keeps the axis slots: bounds[0] is z).
    SliceOptions ox;
    ox.axis = 0;
    ox.layer = 0.25;
    ox.grid = 0.02;
    const SliceResult rx = Slicer(analyticUprightTorus(), uprightTorusBox(), {kDelta}, ox).run();
    const SliceResult qx = applyPlacement(rx, placeSlices(rx, PlacementOptions()));
    CHECK(qx.bounds.min()[0] == 0.0);
    CHECK(qx.bounds.min()[1] == doctest::Approx(2 * 0.02));  // plane u = y: the default plate's margin
    CHECK(qx.layers.front().height == 0.0);

    // The CLI writer with lengths in file units: the numbers are the result's own, $$UNITS is 25.4.
    const fs::path dir = scratch("lib");
    writeCli((dir / "in.cli").string(), q, 25.4, 25.4);
    const RawCli raw = parseCliText(testing::readFile(dir / "in.cli"));
    CHECK(raw.units == 25.4);
    CHECK(raw.z.front() == doctest::Approx(q.layers.front().thickness).epsilon(1e-6));
    CHECK(readCli((dir / "in.cli").string()).layers.front().height ==
          doctest::Approx(25.4 * q.layers.front().thickness).epsilon(1e-6));
  }
}
