// SLA packages (slice --sl1, sl1.hpp), read back with readers written here from the formats' own
// documents, not with libzip or the library's PNG reader:
//  - ZIP (PKWARE APPNOTE.TXT): the end of central directory record (signature 0x06054b50: entry count,
//    directory size and offset), central directory headers (0x02014b50: method, CRC-32, sizes, name,
//    local header offset), local headers (0x04034b50: 30 bytes, then name, extra field, data); method 0
//    stored, 8 deflated (raw DEFLATE, RFC 1951, inflated with zlib);
//  - PNG (ISO/IEC 15948): chunks, IHDR, pHYs, the IDAT stream (zlib), per-row filter types 0-4;
//  - the SL1 layout (PrusaSlicer's SL1 writer): config.ini / prusaslicer.ini "key = value" lines,
//    "<jobDir>00000.png" ..., "thumbnail/thumbnail<W>x<H>.png", and PrusaSlicer's raster transform
//    (portrait: image columns along the plate's y, rows along x; display_mirror_x = 1 then keeps y's
//    direction, and rows run from x = max at the top unless display_mirror_y).
#include <doctest/doctest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cli_runner.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/sl1.hpp"
#include "json_report.hpp"
#include "slice_fixtures.hpp"
#include "temp_dir.hpp"

using namespace duplexfit;
using namespace duplexfit::slicetest;
namespace fs = std::filesystem;

namespace {

constexpr double kPi = 3.14159265358979323846;

std::uint32_t le(const std::string& b, std::size_t at, int bytes) {
  REQUIRE(at + static_cast<std::size_t>(bytes) <= b.size());
  std::uint32_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<unsigned char>(b[at + static_cast<std::size_t>(i)]);
  return v;
}

std::uint32_t be(const std::string& b, std::size_t at) {
  REQUIRE(at + 4 <= b.size());
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(b[at + i]);
  return v;
}

/// Inflates `data` (windowBits −15: raw DEFLATE; 15: a zlib stream) to exactly `size` bytes when size > 0.
std::string inflateAll(const std::string& data, int windowBits, std::size_t size = 0) {
  z_stream z{};
  REQUIRE(inflateInit2(&z, windowBits) == Z_OK);
  std::string out;
  std::vector<unsigned char> buf(1 << 16);
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  int rc = Z_OK;
  while (rc == Z_OK) {
    z.next_out = buf.data();
    z.avail_out = static_cast<uInt>(buf.size());
    rc = inflate(&z, Z_NO_FLUSH);
    REQUIRE_MESSAGE((rc == Z_OK || rc == Z_STREAM_END), "inflate: " << rc);
    out.append(reinterpret_cast<const char*>(buf.data()), buf.size() - z.avail_out);
  }
  inflateEnd(&z);
  if (size > 0) REQUIRE(out.size() == size);
  return out;
}

struct ZipEntry {
  std::string name, data;
  int method = -1;
};

/// Every entry of a zip archive, in central directory order, CRC-checked.
std::vector<ZipEntry> readZip(const std::string& b) {
  REQUIRE(b.size() >= 22);
  std::size_t eocd = std::string::npos;
  for (std::size_t at = b.size() - 22 + 1; at-- > 0 && b.size() - at <= 22 + 65535;) {
    if (le(b, at, 4) == 0x06054b50u) {
      eocd = at;
      break;
    }
  }
  REQUIRE_MESSAGE(eocd != std::string::npos, "no end of central directory record");
  const std::uint32_t count = le(b, eocd + 10, 2), cdSize = le(b, eocd + 12, 4), cdOffset = le(b, eocd + 16, 4);
  REQUIRE(cdOffset + cdSize <= eocd);
  std::vector<ZipEntry> entries;
  std::size_t at = cdOffset;
  for (std::uint32_t k = 0; k < count; ++k) {
    REQUIRE(le(b, at, 4) == 0x02014b50u);
    ZipEntry e;
    e.method = static_cast<int>(le(b, at + 10, 2));
    const std::uint32_t crc = le(b, at + 16, 4), csize = le(b, at + 20, 4), usize = le(b, at + 24, 4);
    REQUIRE((csize != 0xffffffffu && usize != 0xffffffffu));  // no ZIP64 in these small archives
    const std::uint32_t nlen = le(b, at + 28, 2), xlen = le(b, at + 30, 2), clen = le(b, at + 32, 2);
    const std::uint32_t local = le(b, at + 42, 4);
    e.name = b.substr(at + 46, nlen);
    at += 46 + nlen + xlen + clen;
    REQUIRE(le(b, local, 4) == 0x04034b50u);
    CHECK(b.substr(local + 30, le(b, local + 26, 2)) == e.name);
    const std::size_t data = local + 30 + le(b, local + 26, 2) + le(b, local + 28, 2);
    REQUIRE(data + csize <= cdOffset);
    const std::string raw = b.substr(data, csize);
    if (e.method == 0) {
      REQUIRE(csize == usize);
      e.data = raw;
    } else {
      REQUIRE_MESSAGE(e.method == 8, e.name << ": method " << e.method);
      e.data = inflateAll(raw, -15, usize);
    }
    CHECK_MESSAGE(crc32(0L, reinterpret_cast<const Bytef*>(e.data.data()), static_cast<uInt>(e.data.size())) == crc,
                  e.name << ": CRC-32");
    entries.push_back(std::move(e));
  }
  return entries;
}

std::map<std::string, std::string> parseIni(const std::string& text) {
  std::map<std::string, std::string> m;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find(" = ");
    REQUIRE_MESSAGE(eq != std::string::npos, "not 'key = value': " << line);
    CHECK_MESSAGE(m.count(line.substr(0, eq)) == 0, "repeated key " << line);
    m[line.substr(0, eq)] = line.substr(eq + 3);
  }
  return m;
}

double number(const std::map<std::string, std::string>& ini, const std::string& key) {
  const auto it = ini.find(key);
  REQUIRE_MESSAGE(it != ini.end(), "missing key " << key);
  char* end = nullptr;
  const double v = std::strtod(it->second.c_str(), &end);
  REQUIRE_MESSAGE((end != it->second.c_str() && *end == '\0'), key << " = '" << it->second << "' is not a number");
  return v;
}

struct DecodedPng {
  std::uint32_t width = 0, height = 0, physX = 0, physY = 0;
  int bitDepth = 0, colourType = -1, physUnit = -1, channels = 0;
  std::vector<std::uint8_t> pixels;  // rows top to bottom
};

DecodedPng decodePng(const std::string& b) {
  static const char sig[8] = {'\x89', 'P', 'N', 'G', '\r', '\n', '\x1a', '\n'};
  REQUIRE((b.size() >= 8 && std::equal(sig, sig + 8, b.begin())));
  DecodedPng p;
  std::string idat;
  std::size_t at = 8;
  bool end = false;
  while (!end && at + 12 <= b.size()) {
    const std::uint32_t length = be(b, at);
    const std::string type = b.substr(at + 4, 4);
    const std::size_t data = at + 8;
    REQUIRE(data + length + 4 <= b.size());
    CHECK(crc32(0L, reinterpret_cast<const Bytef*>(b.data() + at + 4), length + 4) == be(b, data + length));
    if (type == "IHDR") {
      p.width = be(b, data), p.height = be(b, data + 4);
      p.bitDepth = static_cast<unsigned char>(b[data + 8]);
      p.colourType = static_cast<unsigned char>(b[data + 9]);
      REQUIRE(static_cast<unsigned char>(b[data + 12]) == 0);  // not interlaced
    } else if (type == "pHYs") {
      p.physX = be(b, data), p.physY = be(b, data + 4), p.physUnit = static_cast<unsigned char>(b[data + 8]);
    } else if (type == "IDAT") {
      idat += b.substr(data, length);
    }
    end = type == "IEND";
    at = data + length + 4;
  }
  REQUIRE(end);
  REQUIRE(p.bitDepth == 8);
  p.channels = p.colourType == 0 ? 1 : p.colourType == 2 ? 3 : p.colourType == 6 ? 4 : p.colourType == 4 ? 2 : 0;
  REQUIRE(p.channels > 0);
  const std::size_t stride = static_cast<std::size_t>(p.width) * static_cast<std::size_t>(p.channels);
  const std::string raw = inflateAll(idat, 15, (stride + 1) * p.height);
  p.pixels.assign(stride * p.height, 0);
  const std::size_t bpp = static_cast<std::size_t>(p.channels);
  for (std::size_t y = 0; y < p.height; ++y) {
    const int filter = static_cast<unsigned char>(raw[y * (stride + 1)]);
    REQUIRE((filter >= 0 && filter <= 4));
    std::uint8_t* row = p.pixels.data() + y * stride;
    const std::uint8_t* prev = y > 0 ? row - stride : nullptr;
    for (std::size_t x = 0; x < stride; ++x) {
      const int v = static_cast<unsigned char>(raw[y * (stride + 1) + 1 + x]);
      const int a = x >= bpp ? row[x - bpp] : 0, up = prev ? prev[x] : 0, c = (prev && x >= bpp) ? prev[x - bpp] : 0;
      int pred = 0;
      if (filter == 1) pred = a;
      if (filter == 2) pred = up;
      if (filter == 3) pred = (a + up) / 2;
      if (filter == 4) {
        const int pp = a + up - c, pa = std::abs(pp - a), pb = std::abs(pp - up), pc = std::abs(pp - c);
        pred = pa <= pb && pa <= pc ? a : pb <= pc ? up : c;
      }
      row[x] = static_cast<std::uint8_t>((v + pred) & 0xff);
    }
  }
  return p;
}

/// f = max over spheres of (r − |x − c|) (> 0 inside), with exact ∇f and Hessian of the active sphere.
struct Sphere {
  Eigen::Vector3d c;
  double r;
};
FieldFunction spheres(std::vector<Sphere> list) {
  return [list](const Points& q, FieldDerivatives d) {
    FieldSamples s;
    s.values.resize(q.rows());
    if (d != FieldDerivatives::None) s.gradients.resize(q.rows(), 3);
    if (d == FieldDerivatives::Hessian) s.hessians.resize(q.rows(), 6);
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      const Eigen::Vector3d x = q.row(i).transpose();
      std::size_t best = 0;
      double f = -1e300;
      for (std::size_t k = 0; k < list.size(); ++k) {
        const double v = list[k].r - (x - list[k].c).norm();
        if (v > f) f = v, best = k;
      }
      s.values[i] = f;
      const Eigen::Vector3d u = x - list[best].c;
      const double n = std::max(u.norm(), 1e-300);
      if (d != FieldDerivatives::None) s.gradients.row(i) = -(u / n).transpose();
      if (d == FieldDerivatives::Hessian) {
        const Eigen::Matrix3d h = -(Eigen::Matrix3d::Identity() - u * u.transpose() / (n * n)) / n;
        s.hessians.row(i) << h(0, 0), h(0, 1), h(0, 2), h(1, 1), h(1, 2), h(2, 2);
      }
    }
    return s;
  };
}

std::string layerName(const std::string& job, std::size_t k) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%05zu.png", k);
  return job + buf;
}

fs::path scratch(const std::string& name) { return testing::scratchDir("duplexfit-slice-sl1-test", name); }

/// The fitted upright torus (1 x 0.4 x 1 model units) saved once per process.
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

}  // namespace

TEST_SUITE("slice") {
  TEST_CASE("slice: SL1 package of two analytic spheres read back from the spec (library)") {
    if (!sl1Available()) DUPLEXFIT_SKIP("this build has no libzip (Debian: libzip-dev)");
    // A sphere of radius 10 mm and one of 3 mm whose centre is 15 mm further along +x: the placement centres
    // their x extent [−10, 18] on the plate, so the big one sits 4 mm left of the plate's centre, the small
    // one 11 mm right of it; both centres at the plate's y centre, the big one's bottom on the plate.
    const double R = 10.0, r2 = 3.0, h = 0.5;
    const Eigen::Vector3d c(3.0, -2.0, 5.0), c2 = c + Eigen::Vector3d(15.0, 0.0, 0.0);
    const Eigen::AlignedBox3d box(c - Eigen::Vector3d(R, R, R), c + Eigen::Vector3d(15.0 + r2, R, R));
    SliceOptions so;
    so.layer = h;
    so.grid = 0.1;
    const SliceResult sliced = Slicer(spheres({{c, R}, {c2, r2}}), box, {}, so).run();
    Sl1Options o;  // the Original Prusa SL1: 120.96 x 68.04 mm, 2560 x 1440 px, portrait, mirror x
    o.exposure = 7.5;
    o.initialExposure = 30.0;
    o.fadeLayers = 8;
    PlacementOptions po;
    po.plate = Eigen::Vector2d(o.printer.displayWidth, o.printer.displayHeight);
    const SliceResult placed = applyPlacement(sliced, placeSlices(sliced, po));
    const fs::path dir = scratch("spheres");
    const Sl1Summary summary = writeSl1((dir / "two spheres.sl1").string(), placed, o);

    const std::vector<ZipEntry> zip = readZip(testing::readFile(dir / "two spheres.sl1"));
    const std::size_t n = static_cast<std::size_t>(std::lround(2.0 * R / h));  // 40 layers of 0.5 mm
    REQUIRE(zip.size() == n + 4);
    CHECK(zip[0].name == "config.ini");
    CHECK(zip[1].name == "prusaslicer.ini");
    CHECK(zip[0].method == 8);                    // the text deflated, the PNGs stored
    for (std::size_t k = 0; k < n; ++k) CHECK(zip[2 + k].name == layerName("two spheres", k));
    CHECK(zip[n + 2].name == "thumbnail/thumbnail400x400.png");
    CHECK(zip[n + 3].name == "thumbnail/thumbnail800x480.png");

    const auto config = parseIni(zip[0].data);
    CHECK(config.at("action") == "print");
    CHECK(config.at("jobDir") == "two spheres");
    CHECK(config.at("printerModel") == "SL1");
    CHECK(number(config, "layerHeight") == h);
    CHECK(number(config, "expTime") == 7.5);
    CHECK(number(config, "expTimeFirst") == 30.0);
    CHECK(number(config, "numFade") == 8);
    CHECK(number(config, "numFast") + number(config, "numSlow") == static_cast<double>(n));  // = the PNGs
    CHECK(number(config, "numSlow") == 0);  // no layer exposes half of the display
    // used resin: the spheres' volume within 2% (mm³ → ml)
    const double volume = 4.0 / 3.0 * kPi * (R * R * R + r2 * r2 * r2) / 1000.0;
    CHECK(number(config, "usedMaterial") == doctest::Approx(volume).epsilon(0.02));
    // print time: exposures (the first 8 fading from 30 s to 7.5 s) plus a 5 s fast tilt per layer
    double expected = 0.0;
    for (std::size_t k = 0; k < n; ++k) expected += (k < 8 ? 30.0 + (7.5 - 30.0) * static_cast<double>(k) / 8.0 : 7.5) + 5.0;
    CHECK(number(config, "printTime") == doctest::Approx(expected));
    for (const char* key : {"expUserProfile", "fileCreationTimestamp", "hollow", "materialName", "printProfile",
                            "printerProfile", "printerVariant", "prusaSlicerVersion"}) {
      CHECK_MESSAGE(config.count(key) == 1, key);
    }
    const auto printer = parseIni(zip[1].data);
    CHECK(number(printer, "display_width") == 120.96);
    CHECK(number(printer, "display_height") == 68.04);
    CHECK(number(printer, "display_pixels_x") == 2560);
    CHECK(number(printer, "display_pixels_y") == 1440);
    CHECK(printer.at("display_orientation") == "portrait");
    CHECK(number(printer, "display_mirror_x") == 1);
    CHECK(number(printer, "display_mirror_y") == 0);
    CHECK(number(printer, "layer_height") == h);
    CHECK(number(printer, "exposure_time") == 7.5);
    CHECK(number(printer, "initial_exposure_time") == 30.0);
    CHECK(number(printer, "faded_layers") == 8);
    CHECK(printer.at("printer_technology") == "SLA");

    // Every layer: 1440 x 2560 grey (portrait), 0.04725 mm pixels in pHYs (21164 per metre), white = the
    // spheres' sections at the layer's bottom, k·h above the plate: π(R² − (R − k h)²) (+ the small one).
    const double p = 120.96 / 2560.0, W = 120.96, D = 68.04;
    CHECK(p == doctest::Approx(0.04725));
    for (std::size_t k = 0; k < n; ++k) {
      CAPTURE(k);
      const DecodedPng png = decodePng(zip[2 + k].data);
      REQUIRE(png.width == 1440);
      REQUIRE(png.height == 2560);
      CHECK(png.colourType == 0);
      CHECK(png.physUnit == 1);
      CHECK(png.physX == 21164);
      CHECK(png.physY == 21164);
      std::size_t white = 0, other = 0;
      double sumCol = 0.0, sumRow = 0.0;
      for (std::size_t i = 0; i < png.pixels.size(); ++i) {
        if (png.pixels[i] == 255) {
          ++white;
          sumCol += static_cast<double>(i % 1440) + 0.5;
          sumRow += static_cast<double>(i / 1440) + 0.5;
        } else if (png.pixels[i] != 0) {
          ++other;
        }
      }
      CHECK(other == 0);
      const double z = static_cast<double>(k) * h, d = R - z, d2 = z - R;  // from the big and the small centre
      const double a1 = kPi * std::max(0.0, R * R - d * d), a2 = kPi * std::max(0.0, r2 * r2 - d2 * d2);
      const double area = static_cast<double>(white) * p * p;
      CHECK(summary.exposedArea[k] == doctest::Approx(area));
      if (a1 < 1.0) {  // the first layer cuts 10⁻⁵ mm above the pole
        CHECK(area <= 1.0);
        continue;
      }
      const double perimeter = 2.0 * kPi * (std::sqrt(a1 / kPi) + std::sqrt(a2 / kPi));
      CHECK(std::abs(area - (a1 + a2)) <= 0.02 * (a1 + a2) + perimeter * p);
      // Where the white pixels are: plate (x, y) → column y/p, row 2560 − x/p (portrait, mirror x).
      const double x1 = 0.5 * W - 4.0, x2 = 0.5 * W + 11.0;
      const double xc = (a1 * x1 + a2 * x2) / (a1 + a2);
      CHECK(std::abs(sumCol / static_cast<double>(white) - 0.5 * D / p) <= 1.0);
      CHECK(std::abs(sumRow / static_cast<double>(white) - (2560.0 - xc / p)) <= 1.0);
    }
    const DecodedPng thumb = decodePng(zip[n + 2].data);
    CHECK(thumb.width == 400);
    CHECK(thumb.height == 400);
    CHECK(thumb.colourType == 6);  // RGBA
    const DecodedPng wide = decodePng(zip[n + 3].data);
    CHECK(wide.width == 800);
    CHECK(wide.height == 480);
    // The thumbnail shows the part (the material colour #29B2B2, shaded) at the centre.
    const std::uint8_t* mid = &thumb.pixels[(200 * 400 + 190) * 4];
    CHECK(mid[3] == 255);
    CHECK(mid[1] > mid[0]);
    CHECK(summary.entries.size() == zip.size());
    CHECK(summary.layers == n);
  }

  TEST_CASE("slice: SL1 layer images follow the display's orientation and mirroring") {
    // One layer, a disc at plate (x, y) = (12, 7) mm on a 40 x 30 mm display of 400 x 300 pixels (0.1 mm):
    // its centre lands in display pixel (i, j) = (120, 70) and in the image at the spec's transform.
    SliceOptions so;
    so.layer = 1.0;
    so.grid = 0.05;
    const Eigen::Vector3d c(12.0, 7.0, 0.5);
    const SliceResult r = Slicer(spheres({{c, 2.0}}), Eigen::AlignedBox3d(c - Eigen::Vector3d::Constant(2.0), c + Eigen::Vector3d::Constant(2.0)), {}, so).run();
    SliceLayer layer = r.layers.at(2);  // at z ≈ 0.5 + 0, through the centre
    Sl1Printer p;
    p.displayWidth = 40.0, p.displayHeight = 30.0, p.pixelsX = 400, p.pixelsY = 300;
    const struct {
      Sl1Orientation o;
      bool mx, my;
      int width, col, row;  // image width, expected centre column and row (pixel index + 0.5)
    } cases[] = {
        {Sl1Orientation::Landscape, false, false, 400, 120, 300 - 70},
        {Sl1Orientation::Landscape, true, false, 400, 400 - 120, 300 - 70},
        {Sl1Orientation::Landscape, false, true, 400, 120, 70},
        {Sl1Orientation::Portrait, true, false, 300, 70, 400 - 120},
        {Sl1Orientation::Portrait, false, false, 300, 300 - 70, 400 - 120},
        {Sl1Orientation::Portrait, true, true, 300, 70, 120},
    };
    for (const auto& k : cases) {
      CAPTURE(sl1OrientationName(k.o));
      CAPTURE(k.mx);
      CAPTURE(k.my);
      p.orientation = k.o, p.mirrorX = k.mx, p.mirrorY = k.my;
      const Image img = sl1LayerImage(layer, p);
      REQUIRE(img.width == k.width);
      REQUIRE(img.height == 700 - k.width);
      double sc = 0.0, sr = 0.0, count = 0.0;
      for (int y = 0; y < img.height; ++y) {
        for (int x = 0; x < img.width; ++x) {
          if (*img.at(x, y) == 0) continue;
          sc += x + 0.5, sr += y + 0.5, count += 1.0;
        }
      }
      REQUIRE(count > 0.0);
      CHECK(count * 0.01 == doctest::Approx(kPi * 4.0).epsilon(0.03));
      CHECK(std::abs(sc / count - k.col) <= 0.5);
      CHECK(std::abs(sr / count - k.row) <= 0.5);
    }
    p.pixelsX = 300;  // 0.1333 x 0.1 mm pixels
    CHECK_THROWS_AS((void)sl1LayerImage(layer, p), InvalidArgument);
  }

  TEST_CASE("slice: writeSl1 refuses adaptive layers and parts off the display, leaving no file") {
    if (!sl1Available()) DUPLEXFIT_SKIP("this build has no libzip (Debian: libzip-dev)");
    const fs::path dir = scratch("lib-errors");
    const Eigen::Vector3d c(0.0, 0.0, 0.0);
    const Eigen::AlignedBox3d box(c - Eigen::Vector3d::Constant(5.0), c + Eigen::Vector3d::Constant(5.0));
    SliceOptions adaptive;
    adaptive.cusp = 0.1;
    const SliceResult a = Slicer(spheres({{c, 5.0}}), box, {}, adaptive).run();
    const std::string path = (dir / "a.sl1").string();
    try {
      (void)writeSl1(path, a, Sl1Options());
      FAIL("adaptive layers were accepted");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("uniform layers") != std::string::npos);
      CHECK(std::string(e.what()).find(path) != std::string::npos);
    }
    SliceOptions uniform;
    uniform.layer = 1.0;
    const SliceResult u = Slicer(spheres({{c, 5.0}}), box, {}, uniform).run();  // model coordinates: x < 0
    CHECK_THROWS_AS((void)writeSl1(path, u, Sl1Options()), InvalidArgument);
    Sl1Options bad;
    bad.fadeLayers = 2;
    CHECK_THROWS_WITH_AS((void)writeSl1(path, u, bad), doctest::Contains("--fade-layers"), InvalidArgument);
    CHECK(fs::is_empty(dir));
  }

  TEST_CASE("slice --sl1: the package is part of the output set and slices.json records it") {
    DUPLEXFIT_REQUIRE_CLI();
    if (!sl1Available()) DUPLEXFIT_SKIP("this build has no libzip (Debian: libzip-dev)");
    const fs::path out = scratch("cli");
    // The torus ×10: 10 x 4 x 10 mm, 20 layers of 0.5 mm on the default Original Prusa SL1.
    testing::CliRun run = slice("--layer 0.05 --scale 10 --sl1 torus.sl1 --exposure 6 --initial-exposure 25", out);
    REQUIRE_MESSAGE(run.status == 0, run.err);
    const testing::Json json = testing::readJsonFile(out / "slices.json");
    CHECK(testing::jsonAt(json, "/sl1/file") == "torus.sl1");
    CHECK(testing::jsonNumber(json, "/sl1/layers") == 20);
    CHECK(testing::jsonNumber(json, "/sl1/layer_height") == doctest::Approx(0.5));
    CHECK(testing::jsonNumber(json, "/sl1/pixel") == doctest::Approx(0.04725));
    CHECK(testing::jsonNumber(json, "/sl1/image_px/0") == 1440);
    CHECK(testing::jsonNumber(json, "/sl1/image_px/1") == 2560);
    CHECK(testing::jsonNumber(json, "/sl1/exposure") == 6.0);
    CHECK(testing::jsonNumber(json, "/placement/plate/0") == 120.96);  // the plate is the display
    CHECK(testing::jsonNumber(json, "/placement/plate/1") == 68.04);
    const std::vector<ZipEntry> zip = readZip(testing::readFile(out / "torus.sl1"));
    std::size_t layers = 0;
    for (const ZipEntry& e : zip) layers += e.name.rfind("torus", 0) == 0 ? 1 : 0;
    CHECK(layers == 20);
    const auto config = parseIni(zip.at(0).data);
    CHECK(number(config, "numFast") + number(config, "numSlow") == 20);
    CHECK(number(config, "layerHeight") == 0.5);
    CHECK(number(config, "expTime") == 6.0);
    CHECK(number(config, "expTimeFirst") == 25.0);
    // Each layer's white area is the layer's region (slices.json, mm²).
    const testing::Json jl = testing::jsonAt(json, "/layers");
    REQUIRE(jl.size() == 20);
    const double p = 0.04725;
    for (std::size_t k : {std::size_t{3}, std::size_t{10}, std::size_t{16}}) {
      CAPTURE(k);
      const DecodedPng png = decodePng(zip.at(2 + k).data);
      std::size_t white = 0;
      for (std::uint8_t v : png.pixels) white += v != 0 ? 1 : 0;
      const double area = testing::jsonNumber(jl[k], "/area");
      REQUIRE(area > 1.0);
      CHECK(static_cast<double>(white) * p * p == doctest::Approx(area).epsilon(0.03));
    }
    CHECK(run.out.find("SL1 package: 20 layers") != std::string::npos);

    // A landscape display of 400 x 300 pixels of 0.1 mm, no mirror, hollowed shell.
    const fs::path small = scratch("cli-small");
    run = slice("--layer 0.1 --scale 10 --mode shell --sl1 part.SL1 --sl1-display 40x30 --sl1-pixels 400x300 "
                "--sl1-orientation landscape --sl1-mirror none --fade-layers 5",
                small);
    REQUIRE_MESSAGE(run.status == 0, run.err);
    const std::vector<ZipEntry> z2 = readZip(testing::readFile(small / "part.SL1"));
    const auto c2 = parseIni(z2.at(0).data);
    CHECK(c2.at("jobDir") == "part");
    CHECK(number(c2, "numFade") == 5);
    CHECK(number(c2, "hollow") == 1);
    const auto p2 = parseIni(z2.at(1).data);
    CHECK(p2.at("display_orientation") == "landscape");
    CHECK(number(p2, "display_mirror_x") == 0);
    const DecodedPng img = decodePng(z2.at(2).data);
    CHECK(img.width == 400);
    CHECK(img.height == 300);
    CHECK(img.physX == 10000);
  }

  TEST_CASE("slice --sl1: adaptive layers, a part larger than the display and bad settings are errors") {
    DUPLEXFIT_REQUIRE_CLI();
    if (!sl1Available()) DUPLEXFIT_SKIP("this build has no libzip (Debian: libzip-dev)");
    const fs::path bad = scratch("bad");
    const struct {
      std::string args;
      const char* part;
    } cases[] = {
        {"--cusp 0.01 --scale 10 --sl1 a.sl1", "uniform layers"},
        {"--layer 0.05 --scale 130 --sl1 a.sl1", "larger than the printer's display"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --axis y --sl1-display 20x3 --sl1-pixels 200x30",
         "larger than the printer's display"},
        {"--layer 0.05 --scale 0.4 --units in --sl1 a.sl1", "millimetres"},
        {"--layer 0.05 --scale 10 --place none --sl1 a.sl1", "--place plate"},
        {"--layer 0.05 --scale 10 --plate 100x60 --sl1 a.sl1", "--plate"},
        {"--layer 0.05 --scale 10 --sl1 sub/a.sl1", "without a folder"},
        {"--layer 0.05 --scale 10 --sl1 a.zip", "ending in .sl1"},
        {"--layer 0.05 --scale 10 --sl1 slices.json", "ending in .sl1"},
        {"--layer 0.05 --scale 10 --exposure 5", "--sl1 NAME.sl1"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --sl1-display 100x60 --sl1-pixels 1000x500", "square pixels"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --sl1-pixels 100", "--sl1-pixels"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --sl1-display 0x5", "--sl1-display"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --sl1-orientation up", "--sl1-orientation"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --sl1-mirror z", "--sl1-mirror"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --fade-layers 2", "--fade-layers"},
        {"--layer 0.05 --scale 10 --sl1 a.sl1 --exposure 0", "--exposure"},
        {"--layer 0.05 --scale 200 --sl1 a.sl1 --sl1-display 240x240 --sl1-pixels 2400x2400", "tall"},
    };
    for (const auto& c : cases) {
      CAPTURE(c.args);
      fs::remove_all(bad);
      fs::create_directories(bad);
      const testing::CliRun run = slice(c.args, bad);
      CHECK(run.status == 1);
      CHECK_MESSAGE(run.err.find(c.part) != std::string::npos, run.err);
      CHECK(fs::is_empty(bad));
    }
  }

  TEST_CASE("slice --sl1 without libzip in the build is a clear error with no output") {
    DUPLEXFIT_REQUIRE_CLI();
    if (sl1Available()) DUPLEXFIT_SKIP("this build has libzip (the error cannot happen)");
    const fs::path out = scratch("no-libzip");
    const testing::CliRun run = slice("--layer 0.05 --scale 10 --sl1 a.sl1", out);
    CHECK(run.status == 1);
    CHECK_MESSAGE(run.err.find("no libzip") != std::string::npos, run.err);
    CHECK(fs::is_empty(out));
    CHECK_THROWS_WITH_AS((void)writeSl1((out / "b.sl1").string(), SliceResult(), Sl1Options()),
                         doctest::Contains("libzip"), InvalidArgument);
    CHECK(fs::is_empty(out));
  }
}
