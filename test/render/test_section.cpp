// Section pictures of a fitted sphere (radius 0.5, inward offset 0.1): the image size, the colour of
// pixels from the sign of f, contour lines on the exact circles of the surface and the offset surface,
// point dots, the pixel ↔ world mapping, clear errors, and the `section` command's files and failures.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "cli_runner.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/image.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/section.hpp"
#include "io/io_test_util.hpp"
#include "json_report.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;
namespace fs = std::filesystem;

namespace {

constexpr double kRadius = 0.5;
constexpr double kOffset = 0.1;

const Device& sectionDevice() {
  static const Device device =
      testing::openclTestDevice() != nullptr ? *testing::openclTestDevice() : Device::reference();
  return device;
}

const PointSet& sphereCloud() {
  static const PointSet cloud = [] {
    Points normals;
    Points p = testing::fibonacciSphere(700, kRadius, &normals);
    return PointSet(std::move(p), std::move(normals));
  }();
  return cloud;
}

// One field for the whole suite: the fit is the slow part.
const ImplicitField& sphereField() {
  static const ImplicitField field = [] {
    FitOptions options;
    options.offsets = {kOffset};
    return fit(sectionDevice(), sphereCloud(), options).field;
  }();
  return field;
}

bool near(const std::uint8_t* px, const std::array<std::uint8_t, 3>& c, int tolerance) {
  for (std::size_t k = 0; k < 3; ++k) {
    if (std::abs(static_cast<int>(px[k]) - static_cast<int>(c[k])) > tolerance) return false;
  }
  return true;
}

// Whether a pixel within ±reach pixels of the world point p is within `tolerance` of colour c.
bool colourNear(const SectionResult& r, const Eigen::Vector3d& p, const std::array<std::uint8_t, 3>& c,
                int reach = 2, int tolerance = 70) {
  const Eigen::Vector2d q = r.pixelOf(p);
  const int cx = static_cast<int>(std::floor(q.x())), cy = static_cast<int>(std::floor(q.y()));
  for (int y = cy - reach; y <= cy + reach; ++y) {
    for (int x = cx - reach; x <= cx + reach; ++x) {
      if (x < 0 || y < 0 || x >= r.image.width || y >= r.image.height) continue;
      if (near(r.image.at(x, y), c, tolerance)) return true;
    }
  }
  return false;
}

// A circle of radius rho around the origin in the plane's (right, up) coordinates.
Eigen::Vector3d onCircle(const SectionPlane& plane, double rho, double angle) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  p[plane.axis] = plane.value;
  p[plane.rightAxis()] = rho * std::cos(angle);
  p[plane.upAxis()] = rho * std::sin(angle);
  return p;
}

// Checks the picture of the sphere on `plane` against the exact geometry: red inside the sphere's circle,
// blue outside, black contour on the circle, offset-coloured contour on the offset circle.
void checkSphereSection(const SectionResult& r) {
  const SectionPlane& plane = r.plane;
  const double c2 = plane.value * plane.value;
  const double rho0 = std::sqrt(kRadius * kRadius - c2);
  const double rho1 = std::sqrt((kRadius - kOffset) * (kRadius - kOffset) - c2);
  const auto black = sectionContourColour(0), green = sectionContourColour(1);
  CHECK(black != green);
  // Colours from the sign of f, away (3 px) from both circles.
  int checked = 0, wrong = 0;
  for (int y = 0; y < r.image.height; y += 3) {
    for (int x = 0; x < r.image.width; x += 3) {
      const Eigen::Vector3d p = r.pixelCentre(x, y);
      const double rho = Eigen::Vector2d(p[plane.rightAxis()], p[plane.upAxis()]).norm();
      if (std::abs(rho - rho0) < 3 * r.pixelSize || std::abs(rho - rho1) < 3 * r.pixelSize) continue;
      const std::uint8_t* px = r.image.at(x, y);
      const bool red = px[0] > px[2], blue = px[2] > px[0];
      ++checked;
      // exact geometry: inside the sphere f > 0 → red; outside f < 0 → blue
      if (rho < rho0 ? !red : !blue) ++wrong;
      // and the colour is the colour map of the sampled value
      const float f = r.values[static_cast<std::size_t>(y) * static_cast<std::size_t>(r.image.width) +
                               static_cast<std::size_t>(x)];
      if (!near(px, sectionColour(static_cast<double>(f), r.range), 0)) ++wrong;
    }
  }
  CHECK(checked > 500);
  CHECK(wrong == 0);
  // Contours on the exact circles (within ±2 px), none well away from them.
  int missing0 = 0, missing1 = 0, stray = 0;
  for (int i = 0; i < 72; ++i) {
    const double a = 2.0 * M_PI * i / 72.0;
    missing0 += colourNear(r, onCircle(plane, rho0, a), black) ? 0 : 1;
    missing1 += colourNear(r, onCircle(plane, rho1, a), green) ? 0 : 1;
    for (double rho : {0.5 * rho1, 0.5 * (rho0 + rho1), rho0 + 0.03}) {
      const Eigen::Vector2d q = r.pixelOf(onCircle(plane, rho, a));
      const int x = static_cast<int>(q.x()), y = static_cast<int>(q.y());
      REQUIRE(x >= 0);
      REQUIRE(y >= 0);
      REQUIRE(x < r.image.width);
      REQUIRE(y < r.image.height);
      const std::uint8_t* px = r.image.at(x, y);
      stray += near(px, black, 70) || near(px, green, 70) ? 1 : 0;
    }
  }
  CHECK(missing0 == 0);
  CHECK(missing1 == 0);
  CHECK(stray == 0);
}

using testing::CliRun;
using testing::Json;
using testing::jsonAt;

CliRun cli(const std::string& args) { return testing::runCli(args); }

// The file names of a section --json output's "files" and "sections[].file" (one "?" per entry that is not
// a string).
std::vector<std::string> jsonFileNames(const Json& out, const std::string& pointer) {
  std::vector<std::string> names;
  const Json files = jsonAt(out, pointer);
  if (!files.is_array()) return names;
  for (const Json& f : files) {
    const Json name = f.is_object() ? jsonAt(f, "/file") : f;
    names.push_back(name.is_string() ? fs::path(name.get<std::string>()).filename().string() : "?");
  }
  return names;
}

}  // namespace

TEST_SUITE("render") {
  TEST_CASE("section: planes parse and print; bad plane texts are InvalidArgument") {
    const SectionPlane z = SectionPlane::parse("z=0.1");
    CHECK(z.axis == 2);
    CHECK(z.value == 0.1);
    CHECK(z.toString() == "z=0.1");
    const SectionPlane x = SectionPlane::parse(" X = -2.5 ");
    CHECK(x.axis == 0);
    CHECK(x.value == -2.5);
    CHECK(x.rightAxis() == 1);
    CHECK(x.upAxis() == 2);
    CHECK(SectionPlane::parse("y=1e-3").toString() == "y=0.001");
    CHECK(SectionPlane{1, 0.0}.rightAxis() == 0);
    CHECK(SectionPlane{1, 0.0}.upAxis() == 2);
    for (const char* bad : {"", "w=1", "z", "z=", "z=abc", "z=1 2", "z=nan", "zz=1"}) {
      CAPTURE(bad);
      try {
        SectionPlane::parse(bad);
        FAIL("expected InvalidArgument");
      } catch (const InvalidArgument& e) {
        CHECK(std::string(e.what()).find("section plane '" + std::string(bad) + "'") != std::string::npos);
      }
    }
    // The colour map: white at 0, blue below, red above, saturating at ±range.
    CHECK(sectionColour(0.0, 1.0) == std::array<std::uint8_t, 3>{255, 255, 255});
    const auto blue = sectionColour(-2.0, 1.0), red = sectionColour(2.0, 1.0);
    CHECK(blue == sectionColour(-1.0, 1.0));
    CHECK(blue[2] > blue[0] + 100);
    CHECK(red[0] > red[2] + 100);
    CHECK(sectionContourColour(1) != sectionContourColour(2));
    CHECK(sectionColour(0.25, 1.0, 0.5) == sectionColour(0.5, 1.0, 1.0));
    CHECK(sectionColour(-0.25, 1.0) == sectionColour(-0.5, 1.0, 1.0));  // default gamma 0.5
    CHECK(sectionColour(std::nan(""), 1.0) == std::array<std::uint8_t, 3>{128, 128, 128});
  }

  TEST_CASE("section: the sphere on z=0 has the requested size, colours by sign and contours on the circles") {
    const ImplicitField& field = sphereField();
    const SectionResult r = renderSection(sectionDevice(), field, SectionPlane{2, 0.0}, [] {
      SectionOptions o;
      o.size = 160;
      return o;
    }());
    const Eigen::Vector3d size = field.bounds().sizes();
    CHECK(std::max(r.image.width, r.image.height) == 160);
    CHECK(std::abs(static_cast<double>(r.image.width) / r.image.height - size.x() / size.y()) < 0.02);
    CHECK(r.image.channels == 3);
    CHECK(r.values.size() == static_cast<std::size_t>(r.image.width) * static_cast<std::size_t>(r.image.height));
    CHECK(r.levels == std::vector<double>{0.0, kOffset});
    CHECK(r.pixelSize == doctest::Approx(1.1 * size.x() / 160).epsilon(0.01));  // box + 5% on each side
    CHECK(r.minValue < 0.0);
    CHECK(r.maxValue > kOffset);
    CHECK(r.range > 0.0);
    // The image's pixels are f at their centres (the device agrees with the reference path).
    for (const auto& [x, y] : {std::pair{80, 80}, {10, 20}, {120, 40}, {3, 150}}) {
      CAPTURE(x);
      CAPTURE(y);
      const float f = r.values[static_cast<std::size_t>(y * r.image.width + x)];
      CHECK(static_cast<double>(f) == doctest::Approx(field.value(r.pixelCentre(x, y))).epsilon(1e-3).scale(1e-3));
    }
    // The picture's orientation: x to the right, y up, the top row first.
    CHECK(r.pixelCentre(0, 0).x() < r.pixelCentre(1, 0).x());
    CHECK(r.pixelCentre(0, 0).y() > r.pixelCentre(0, 1).y());
    CHECK(r.pixelCentre(5, 7).z() == 0.0);
    CHECK((r.pixelOf(r.pixelCentre(5, 7)) - Eigen::Vector2d(5.5, 7.5)).norm() < 1e-9);
    // The centre is red (inside, f > 0), the corner blue (outside, f < 0).
    const std::uint8_t* centre = r.image.at(r.image.width / 2, r.image.height / 2);
    CHECK(centre[0] > centre[2]);
    CHECK(r.image.at(0, 0)[2] > r.image.at(0, 0)[0]);
    checkSphereSection(r);
  }

  TEST_CASE("section: off-centre x and y planes, a user range and a user rectangle") {
    const ImplicitField& field = sphereField();
    const FieldEvaluator evaluator(sectionDevice(), field);
    SectionOptions o;
    o.size = 128;
    const SectionResult rx = renderSection(evaluator, field, SectionPlane{0, 0.3}, o);
    CHECK(std::max(rx.image.width, rx.image.height) == 128);
    CHECK(rx.pixelCentre(3, 3).x() == 0.3);
    checkSphereSection(rx);
    const SectionResult ry = renderSection(evaluator, field, SectionPlane{1, -0.2}, o);
    checkSphereSection(ry);

    o.range = 2.0;
    o.rectangle = Eigen::AlignedBox2d(Eigen::Vector2d(0.0, 0.0), Eigen::Vector2d(0.6, 0.3));
    const SectionResult rr = renderSection(evaluator, field, SectionPlane{2, 0.0}, o);
    CHECK(rr.image.width == 128);
    CHECK(rr.image.height == 64);
    CHECK(rr.range == 2.0);
    CHECK(rr.rectangle.min().isApprox(Eigen::Vector2d(0.0, 0.0)));
    CHECK(rr.rectangle.max().isApprox(Eigen::Vector2d(0.6, 0.3)));
    CHECK(rr.pixelSize == doctest::Approx(0.6 / 128));
    // Bottom-left pixel is near the origin (inside): light red on a ±2 scale.
    const float f = rr.values[static_cast<std::size_t>(63 * 128)];
    CHECK(near(rr.image.at(0, 63), sectionColour(static_cast<double>(f), 2.0, o.gamma), 0));
    CHECK(rr.image.at(0, 63)[0] > rr.image.at(0, 63)[2]);
    // Without contours only the colour map remains.
    o.contours = false;
    o.gamma = 1.0;
    const SectionResult rn = renderSection(evaluator, field, SectionPlane{2, 0.0}, o);
    for (int y = 0; y < rn.image.height; ++y) {
      for (int x = 0; x < rn.image.width; ++x) {
        const float v = rn.values[static_cast<std::size_t>(y * rn.image.width + x)];
        REQUIRE(near(rn.image.at(x, y), sectionColour(static_cast<double>(v), 2.0, 1.0), 0));
      }
    }
  }

  TEST_CASE("section: points within the band are drawn as dots") {
    const ImplicitField& field = sphereField();
    SectionOptions o;
    o.size = 128;
    o.points = sphereCloud().positions();
    o.band = 0.02;
    const SectionResult r = renderSection(sectionDevice(), field, SectionPlane{2, 0.0}, o);
    std::size_t inBand = 0, dotted = 0;
    for (Eigen::Index i = 0; i < o.points.rows(); ++i) {
      if (std::abs(o.points(i, 2)) >= 0.02) continue;
      ++inBand;
      const Eigen::Vector2d q = r.pixelOf(o.points.row(i).transpose());
      dotted += near(r.image.at(static_cast<int>(q.x()), static_cast<int>(q.y())), sectionPointColour(), 40) ? 1 : 0;
    }
    CHECK(inBand > 5);
    CHECK(r.pointsDrawn == inBand);
    CHECK(dotted == inBand);
    CHECK(r.band == 0.02);
    // The default band: 1% of the box's longest side.
    o.band = 0.0;
    const SectionResult d = renderSection(sectionDevice(), field, SectionPlane{2, 0.0}, o);
    CHECK(d.band == doctest::Approx(0.01 * field.bounds().sizes().maxCoeff()));
    CHECK(d.pointsDrawn < inBand);
  }

  TEST_CASE("section: a plane outside the box, bad sizes and bad options are InvalidArgument") {
    const ImplicitField& field = sphereField();
    SectionOptions o;
    o.size = 64;
    try {
      renderSection(Device::reference(), field, SectionPlane{2, 0.7}, o);
      FAIL("expected InvalidArgument");
    } catch (const InvalidArgument& e) {
      const std::string m = e.what();
      CHECK(m.find("z=0.7") != std::string::npos);
      CHECK(m.find("box") != std::string::npos);
      CHECK(m.find("0.49") != std::string::npos);  // the box
    }
    CHECK_THROWS_AS(renderSection(Device::reference(), field, SectionPlane{0, -0.51}, o), InvalidArgument);
    CHECK_THROWS_AS(validateSection(field, SectionPlane{1, 0.6}, o), InvalidArgument);
    CHECK_NOTHROW(validateSection(field, SectionPlane{1, field.bounds().max().y()}, o));  // on the box is fine
    for (int size : {0, 15, 16385, -3}) {
      CAPTURE(size);
      o.size = size;
      CHECK_THROWS_WITH_AS(renderSection(Device::reference(), field, SectionPlane{2, 0.0}, o),
                           doctest::Contains("size"), InvalidArgument);
    }
    o.size = 16;
    CHECK(renderSection(Device::reference(), field, SectionPlane{2, 0.0}, o).image.width == 16);
    SectionOptions bad = o;
    bad.range = -1.0;
    CHECK_THROWS_AS(renderSection(Device::reference(), field, SectionPlane{2, 0.0}, bad), InvalidArgument);
    bad = o;
    bad.band = std::nan("");
    CHECK_THROWS_AS(renderSection(Device::reference(), field, SectionPlane{2, 0.0}, bad), InvalidArgument);
    bad = o;
    bad.rectangle = Eigen::AlignedBox2d(Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0));
    CHECK_THROWS_AS(renderSection(Device::reference(), field, SectionPlane{2, 0.0}, bad), InvalidArgument);
    bad = o;
    bad.gamma = 0.0;
    CHECK_THROWS_WITH_AS(renderSection(Device::reference(), field, SectionPlane{2, 0.0}, bad),
                         doctest::Contains("gamma"), InvalidArgument);
    CHECK_THROWS_AS(renderSection(Device::reference(), field, SectionPlane{3, 0.0}, o), InvalidArgument);
    CHECK_THROWS_AS(renderSection(Device::reference(), ImplicitField(), SectionPlane{2, 0.0}, o), InvalidArgument);
  }

  TEST_CASE("section CLI: three planes without --plane, one with it, JSON; failures leave no output") {
    DUPLEXFIT_REQUIRE_CLI();
    testing::TempDir dir;
    const fs::path fieldPath = dir.path() / "sphere.dpxf";
    sphereField().save(fieldPath.string());
    const std::string field = fieldPath.string();

    // Three files OUT_x/y/z.png, the longer side as asked.
    CliRun r = cli("section " + field + " -o " + dir.file("sec.png") + " --size 48 --device ref --quiet");
    INFO("stderr: " << r.err);
    REQUIRE(r.status == 0);
    CHECK(r.err.empty());
    for (const char* axis : {"x", "y", "z"}) {
      const Image image = readPng(dir.file(std::string("sec_") + axis + ".png"));
      CHECK(std::max(image.width, image.height) == 48);
      CHECK(image.channels == 3);
    }
    CHECK(dir.entries() == std::vector<std::string>{"sec_x.png", "sec_y.png", "sec_z.png", "sphere.dpxf"});

    // -o FOLDER: section_x.png ... inside it; --json names the files.
    fs::create_directory(dir.path() / "pics");
    r = cli("section " + field + " -o " + dir.file("pics") + " --size 32 --device ref --json --quiet");
    REQUIRE(r.status == 0);
    for (const char* name : {"section_x.png", "section_y.png", "section_z.png"}) {
      CHECK(fs::exists(dir.path() / "pics" / name));
    }
    const Json three = testing::parseJson(r.out);
    const std::vector<std::string> names{"section_x.png", "section_y.png", "section_z.png"};
    CHECK(jsonFileNames(three, "/files") == names);
    CHECK(jsonFileNames(three, "/sections") == names);
    for (const Json& section : jsonAt(three, "/sections")) {
      CHECK(jsonAt(section, "/pixel_size").is_number());
      CHECK(jsonAt(section, "/range").is_number());
    }

    // One plane, with points; the picture is the library's.
    const fs::path cloud = dir.path() / "cloud.ply";
    writePointCloud(cloud.string(), sphereCloud());
    r = cli("section " + field + " --plane z=0.1 --size 40 --points " + cloud.string() + " --band 0.03 -o " +
                dir.file("one.png") + " --device ref --json");
    INFO("stderr: " << r.err);
    REQUIRE(r.status == 0);
    const Json single = testing::parseJson(r.out);
    CHECK(jsonFileNames(single, "/files") == std::vector<std::string>{"one.png"});
    CHECK(jsonAt(single, "/sections/0/plane") == "z=0.1");
    CHECK(jsonAt(single, "/sections/0/points_drawn").is_number());
    CHECK(r.err.find("section z=0.1") != std::string::npos);  // progress without --quiet
    const Image one = readPng(dir.file("one.png"));
    SectionOptions o;
    o.size = 40;
    o.points = sphereCloud().positions();
    o.band = 0.03;
    CHECK(one.pixels == renderSection(Device::reference(), sphereField(), SectionPlane{2, 0.1}, o).image.pixels);

    // Failures: a clear message, a non-zero status, nothing written.
    const fs::path outDir = dir.path() / "out";
    fs::create_directory(outDir);
    auto expectFailure = [&](const std::string& args, int status, std::initializer_list<const char*> parts) {
      const CliRun f = cli("section " + args + " --device ref --quiet");
      INFO("args: " << args << "\nstderr: " << f.err);
      CHECK(f.status == status);
      for (const char* part : parts) CHECK(f.err.find(part) != std::string::npos);
      CHECK(fs::is_empty(outDir));
    };
    const std::string out = " -o " + (outDir / "s.png").string();
    expectFailure(field + " --plane z=0.9" + out, 1, {"z=0.9", "box"});
    expectFailure(field + " --plane z=0.9 -o " + outDir.string(), 1, {"z=0.9"});
    expectFailure(field + " --size 0" + out, 1, {"size"});
    expectFailure(field + " --size 20000" + out, 1, {"size"});
    expectFailure(field + " --plane w=1" + out, 1, {"w=1"});
    expectFailure(field + " --band 0.1" + out, 1, {"--points"});
    expectFailure(field, 1, {"-o"});
    expectFailure(dir.file("missing.dpxf") + out, 2, {"missing.dpxf"});
    expectFailure(field + " --points " + dir.file("nocloud.ply") + out, 2, {"nocloud.ply"});
    const std::string bytes = testing::readBytes(field);
    testing::writeBytes(dir.file("cut.dpxf"), bytes.substr(0, bytes.size() / 2));
    expectFailure(dir.file("cut.dpxf") + out, 2, {"cut.dpxf"});
    std::string flipped = bytes;
    flipped[flipped.size() / 2] = static_cast<char>(flipped[flipped.size() / 2] ^ 0x5a);
    testing::writeBytes(dir.file("flipped.dpxf"), flipped);
    expectFailure(dir.file("flipped.dpxf") + out, 2, {"flipped.dpxf"});
    // An unwritable destination: a folder that cannot be created (a file is in the way). Missing folders
    // that can be are created, as fit and slice create theirs (test/cli, "behaves like a CLI").
    testing::writeBytes(dir.file("plain"), "a file, not a folder");
    expectFailure(field + " --size 24 -o " + (dir.path() / "plain" / "sub" / "s.png").string(), 2, {"plain"});
  }
}
