// SLA packages in the layout of PrusaSlicer's SL1 archive (sl1.hpp). What the layout is, from PrusaSlicer's
// SL1 writer (src/libslic3r/Format/SL1.cpp), its raster transform (src/libslic3r/SLA/RasterBase.hpp), its
// configuration defaults (src/libslic3r/PrintConfig.cpp) and the Original Prusa SL1 printer profile as
// UVtools documents it (UVtools.Core/FileFormats/SL1File.cs):
//  - a zip archive; "config.ini" and "prusaslicer.ini" hold "key = value" lines;
//  - config.ini: action = print, jobDir, expTime, expTimeFirst, layerHeight, numFade, numFast, numSlow,
//    printTime (s), usedMaterial (ml), materialName, printerModel, printerProfile, printerVariant,
//    printProfile, prusaSlicerVersion, fileCreationTimestamp, hollow, expUserProfile;
//  - layer k's image is "<jobDir><k as 5 digits>.png", k from 0, an 8-bit grey PNG of the display;
//  - thumbnails are "thumbnail/thumbnail<W>x<H>.png" (RGBA), the SL1 profile asking for 400x400 and 800x480;
//  - prusaslicer.ini: display_width/height (mm) and display_pixels_x/y along the plate's x and y,
//    display_orientation (portrait: the image is display_pixels_y wide, the axes swapped), display_mirror_x/y;
//    the SL1: 120.96 x 68.04 mm, 2560 x 1440 pixels, portrait, mirror x; exposure_time 10 s,
//    initial_exposure_time 15 s and faded_layers 10 (3..20) are PrusaSlicer's defaults.
// Only facts about the format come from there; the code is ours. The zip is built in memory with libzip
// (optional: DUPLEXFIT_HAVE_LIBZIP) and written through an AtomicFile.
#include "duplexfit/sl1.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/version.hpp"

#ifdef DUPLEXFIT_HAVE_LIBZIP
#include <zip.h>
#endif

namespace duplexfit {

namespace {

std::string num(double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.10g", v == 0.0 ? 0.0 : v);
  return buf;
}

/// A job name fit for config.ini and the layer images' names: printable ASCII, no path separators, no '='.
bool goodJobName(const std::string& name) {
  if (name.empty() || name.size() > 200 || name.front() == '.' || name.front() == ' ' || name.back() == ' ') {
    return false;
  }
  for (char c : name) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 || u > 0x7e || c == '/' || c == '\\' || c == '=') return false;
  }
  return true;
}

bool goodText(const std::string& text) {
  for (char c : text) {
    if (c == '\n' || c == '\r') return false;
  }
  return true;
}

/// Image column and row of display pixel (i, j) (i along x, j along y): PrusaSlicer's raster transform
/// (portrait swaps the axes and mirrors x once more; the default flips y so that row 0 is the top).
struct DisplayMap {
  int nx, ny, width, height;
  Sl1Orientation orientation;
  bool mirrorX, mirrorY;
  explicit DisplayMap(const Sl1Printer& p)
      : nx(p.pixelsX), ny(p.pixelsY), width(p.orientation == Sl1Orientation::Portrait ? p.pixelsY : p.pixelsX),
        height(p.orientation == Sl1Orientation::Portrait ? p.pixelsX : p.pixelsY), orientation(p.orientation),
        mirrorX(p.mirrorX), mirrorY(p.mirrorY) {}
  std::pair<int, int> operator()(int i, int j) const {
    if (orientation == Sl1Orientation::Landscape) {
      return {mirrorX ? nx - 1 - i : i, mirrorY ? j : ny - 1 - j};
    }
    return {mirrorX ? j : ny - 1 - j, mirrorY ? i : nx - 1 - i};
  }
};

/// The layer's region on the display: rasterizeLayer over the plate, row r = ny − 1 − j.
Image displayRaster(const SliceLayer& layer, const Sl1Printer& printer) {
  const double p = printer.pixel();
  const Eigen::AlignedBox2d area(Eigen::Vector2d::Zero(), Eigen::Vector2d(printer.pixelsX * p, printer.pixelsY * p));
  return rasterizeLayer(layer, area, p);
}

Image transformed(const Image& plate, const Sl1Printer& printer) {
  const DisplayMap map(printer);
  Image out(map.width, map.height, 1, 0);
  for (int r = 0; r < plate.height; ++r) {
    const int j = map.ny - 1 - r;
    const std::uint8_t* row = plate.at(0, r);
    for (int i = 0; i < plate.width; ++i) {
      if (row[i] == 0) continue;
      const auto [c, rr] = map(i, j);
      *out.at(c, rr) = row[i];
    }
  }
  return out;
}

std::string ini(const std::vector<std::pair<std::string, std::string>>& entries) {
  std::string out;
  for (const auto& [key, value] : entries) out += key + " = " + value + "\n";
  return out;
}

std::string utcTimestamp() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof buf, "%Y-%m-%d at %H:%M:%S UTC", &tm);
  return buf;
}

/// A thumbnail: the part seen from above, each plate point shaded by the height of the top layer covering it
/// (`top`: per display pixel (i, j) at i + j·nx, 0 = none), fitted into w × h with the plate's aspect, RGBA.
Image thumbnail(const std::vector<std::uint32_t>& top, std::size_t layers, const Sl1Printer& printer, int w, int h) {
  Image img(w, h, 4, 0);
  const double scale = std::min(static_cast<double>(w) / printer.pixelsX, static_cast<double>(h) / printer.pixelsY);
  const double ox = 0.5 * (w - scale * printer.pixelsX), oy = 0.5 * (h - scale * printer.pixelsY);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      std::uint8_t* px = img.at(x, y);
      const double fi = (x + 0.5 - ox) / scale, fj = printer.pixelsY - (y + 0.5 - oy) / scale;  // y up
      if (fi < 0.0 || fj < 0.0 || fi >= printer.pixelsX || fj >= printer.pixelsY) continue;  // transparent
      const auto i = static_cast<std::size_t>(fi), j = static_cast<std::size_t>(fj);
      const std::uint32_t t = top[i + j * static_cast<std::size_t>(printer.pixelsX)];
      if (t == 0) {
        px[0] = px[1] = px[2] = 40;  // the display
        px[3] = 255;
        continue;
      }
      const double shade = 0.35 + 0.65 * static_cast<double>(t) / static_cast<double>(std::max<std::size_t>(layers, 1));
      px[0] = static_cast<std::uint8_t>(std::lround(0x29 * shade));  // PrusaSlicer's default material colour
      px[1] = static_cast<std::uint8_t>(std::lround(0xb2 * shade));  // #29B2B2, darker lower down
      px[2] = static_cast<std::uint8_t>(std::lround(0xb2 * shade));
      px[3] = 255;
    }
  }
  return img;
}

/// The package's files, in order: name, bytes, compressed (false: stored, the PNGs being deflated already).
struct Entry {
  std::string name;
  std::vector<std::uint8_t> bytes;
  bool deflate = false;
};

#ifdef DUPLEXFIT_HAVE_LIBZIP

/// The zip archive of `entries`, built in memory.
std::vector<std::uint8_t> zipArchive(const std::vector<Entry>& entries, const std::string& path) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* buffer = zip_source_buffer_create(nullptr, 0, 0, &error);
  if (buffer == nullptr) {
    const std::string message = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw IoError(path + ": cannot create the zip buffer (" + message + ")");
  }
  zip_source_keep(buffer);  // still ours after zip_close, to read the archive back
  zip_t* archive = zip_open_from_source(buffer, ZIP_TRUNCATE, &error);
  if (archive == nullptr) {
    const std::string message = zip_error_strerror(&error);
    zip_error_fini(&error);
    zip_source_free(buffer);
    zip_source_free(buffer);
    throw IoError(path + ": cannot open the zip archive (" + message + ")");
  }
  zip_error_fini(&error);
  const std::time_t now = std::time(nullptr);
  auto fail = [&](const std::string& what) {
    const std::string message = zip_strerror(archive);
    zip_discard(archive);
    zip_source_free(buffer);
    return IoError(path + ": " + what + " (libzip: " + message + ")");
  };
  for (const Entry& e : entries) {
    zip_source_t* source = zip_source_buffer(archive, e.bytes.data(), e.bytes.size(), 0);  // read at zip_close
    if (source == nullptr) throw fail("cannot add " + e.name);
    const zip_int64_t index = zip_file_add(archive, e.name.c_str(), source, ZIP_FL_ENC_UTF_8);
    if (index < 0) {
      zip_source_free(source);
      throw fail("cannot add " + e.name);
    }
    const auto at = static_cast<zip_uint64_t>(index);
    if (zip_set_file_compression(archive, at, e.deflate ? ZIP_CM_DEFLATE : ZIP_CM_STORE, 0) != 0 ||
        zip_file_set_mtime(archive, at, now, 0) != 0) {
      throw fail("cannot set the compression of " + e.name);
    }
  }
  if (zip_close(archive) != 0) throw fail("cannot finish the zip archive");
  std::vector<std::uint8_t> bytes;
  zip_stat_t st;
  zip_stat_init(&st);
  if (zip_source_stat(buffer, &st) != 0 || (st.valid & ZIP_STAT_SIZE) == 0 || zip_source_open(buffer) != 0) {
    zip_source_free(buffer);
    throw IoError(path + ": cannot read the zip archive back from memory");
  }
  bytes.resize(static_cast<std::size_t>(st.size));
  const zip_int64_t read = zip_source_read(buffer, bytes.data(), st.size);
  zip_source_close(buffer);
  zip_source_free(buffer);
  if (read < 0 || static_cast<zip_uint64_t>(read) != st.size) {
    throw IoError(path + ": cannot read the zip archive back from memory");
  }
  return bytes;
}

#endif

}  // namespace

const char* sl1OrientationName(Sl1Orientation orientation) noexcept {
  return orientation == Sl1Orientation::Portrait ? "portrait" : "landscape";
}

Sl1Orientation parseSl1Orientation(const std::string& text) {
  if (text == "portrait") return Sl1Orientation::Portrait;
  if (text == "landscape") return Sl1Orientation::Landscape;
  throw InvalidArgument("display orientation '" + text + "' (--sl1-orientation) is not 'portrait' or 'landscape'");
}

bool sl1Available() noexcept {
#ifdef DUPLEXFIT_HAVE_LIBZIP
  return true;
#else
  return false;
#endif
}

void validateSl1Options(const Sl1Options& o) {
  const Sl1Printer& p = o.printer;
  if (!(p.displayWidth > 0.0 && p.displayHeight > 0.0) || !std::isfinite(p.displayWidth) ||
      !std::isfinite(p.displayHeight)) {
    throw InvalidArgument("--sl1-display: the display must be W x H millimetres, both > 0 (got " +
                          num(p.displayWidth) + " x " + num(p.displayHeight) + ")");
  }
  if (p.pixelsX < 1 || p.pixelsY < 1 || p.pixelsX > 65536 || p.pixelsY > 65536) {
    throw InvalidArgument("--sl1-pixels: the display must be 1 to 65536 pixels a side (got " +
                          std::to_string(p.pixelsX) + " x " + std::to_string(p.pixelsY) + ")");
  }
  const double px = p.displayWidth / p.pixelsX, py = p.displayHeight / p.pixelsY;
  if (std::abs(px - py) > 1e-6 * std::max(px, py)) {
    throw InvalidArgument("--sl1-display " + num(p.displayWidth) + "x" + num(p.displayHeight) + " with --sl1-pixels " +
                          std::to_string(p.pixelsX) + "x" + std::to_string(p.pixelsY) + ": the pixels are " +
                          num(px) + " x " + num(py) + " mm; only square pixels are supported");
  }
  if (!(p.maxPrintHeight > 0.0) || !(p.fastTiltTime >= 0.0) || !(p.slowTiltTime >= 0.0) ||
      !(p.areaFill >= 0.0 && p.areaFill <= 100.0)) {
    throw InvalidArgument("SL1 printer: max print height > 0, tilt times >= 0 and area fill in 0..100 %");
  }
  if (!(o.exposure > 0.0) || !std::isfinite(o.exposure)) {
    throw InvalidArgument("--exposure must be > 0 seconds (got " + num(o.exposure) + ")");
  }
  if (!(o.initialExposure > 0.0) || !std::isfinite(o.initialExposure)) {
    throw InvalidArgument("--initial-exposure must be > 0 seconds (got " + num(o.initialExposure) + ")");
  }
  if (o.fadeLayers < 3 || o.fadeLayers > 20) {
    throw InvalidArgument("--fade-layers must be 3 to 20 (PrusaSlicer's faded_layers), got " +
                          std::to_string(o.fadeLayers));
  }
  if (!o.jobName.empty() && !goodJobName(o.jobName)) {
    throw InvalidArgument("SL1 job name '" + o.jobName +
                          "': printable ASCII without '/', '\\' or '=', not starting with '.'");
  }
  for (const std::string* text : {&p.model, &p.profile, &p.variant, &o.materialName, &o.printProfile}) {
    if (!goodText(*text)) throw InvalidArgument("SL1 settings: '" + *text + "' holds a line break");
  }
  for (const auto& [w, h] : o.thumbnails) {
    if (w < 1 || h < 1 || w > 4096 || h > 4096) {
      throw InvalidArgument("SL1 thumbnail " + std::to_string(w) + "x" + std::to_string(h) + ": 1 to 4096 a side");
    }
  }
}

Image sl1LayerImage(const SliceLayer& layer, const Sl1Printer& printer) {
  Sl1Options o;
  o.printer = printer;
  validateSl1Options(o);
  return transformed(displayRaster(layer, printer), printer);
}

Sl1Summary writeSl1(const std::string& path, const SliceResult& placed, const Sl1Options& options) {
  if (!sl1Available()) {
    throw InvalidArgument(path + ": this build of duplexfit has no libzip (Debian: libzip-dev), so it cannot write "
                                 "SL1 packages (--sl1); rebuild with libzip-dev installed");
  }
  validateSl1Options(options);
  const Sl1Printer& printer = options.printer;
  Sl1Summary s;
  s.jobName = options.jobName.empty() ? std::filesystem::path(path).stem().string() : options.jobName;
  if (!goodJobName(s.jobName)) {
    throw InvalidArgument(path + ": the job name '" + s.jobName +
                          "' (the file's name without .sl1) must be printable ASCII without '/', '\\' or '='");
  }
  if (placed.layers.empty()) throw InvalidArgument(path + ": no layers to write");
  if (placed.adaptive || !(placed.layer > 0.0)) {
    throw InvalidArgument(path + ": an SL1 package has one layer height; slice with uniform layers (--layer H)");
  }
  const double h = placed.layer;
  for (std::size_t k = 0; k < placed.layers.size(); ++k) {
    if (std::abs(placed.layers[k].thickness - h) > 1e-9 * h) {
      throw InvalidArgument(path + ": layer " + std::to_string(k + 1) + " is " + num(placed.layers[k].thickness) +
                            " mm thick, not the uniform " + num(h) + " mm");
    }
  }
  // The part must lie on the display [0, W] x [0, D] and below the printer's height.
  const double tol = 1e-9 * std::max(printer.displayWidth, printer.displayHeight);
  Eigen::AlignedBox2d extent;
  for (const SliceLayer& layer : placed.layers) {
    for (const SliceLoop& loop : layer.loops) {
      for (Eigen::Index i = 0; i < loop.points.rows(); ++i) extent.extend(Eigen::Vector2d(loop.points(i, 0), loop.points(i, 1)));
    }
  }
  if (!extent.isEmpty() && (extent.min().x() < -tol || extent.min().y() < -tol ||
                            extent.max().x() > printer.displayWidth + tol || extent.max().y() > printer.displayHeight + tol)) {
    throw InvalidArgument(path + ": the part (x " + num(extent.min().x()) + " to " + num(extent.max().x()) + ", y " +
                          num(extent.min().y()) + " to " + num(extent.max().y()) + " mm) is not on the display (" +
                          num(printer.displayWidth) + " x " + num(printer.displayHeight) + " mm)");
  }
  const double top = placed.layers.back().height + placed.layers.back().thickness;
  if (top > printer.maxPrintHeight + tol) {
    throw InvalidArgument(path + ": the part is " + num(top) + " mm tall, more than the printer's " +
                          num(printer.maxPrintHeight) + " mm");
  }

  const double p = printer.pixel();
  const double displayPixels = static_cast<double>(printer.pixelsX) * printer.pixelsY;
  const double perMetre = std::round(1000.0 / p);
  const std::uint32_t ppm = perMetre >= 1.0 && perMetre <= 2147483647.0 ? static_cast<std::uint32_t>(perMetre) : 0u;
  s.layers = placed.layers.size();
  s.layerHeight = h;
  s.pixel = p;
  const DisplayMap map(printer);
  s.imageWidth = map.width;
  s.imageHeight = map.height;
  std::vector<Entry> entries(2);  // config.ini and prusaslicer.ini, filled in once the layers are counted
  std::vector<std::uint32_t> topLayer(static_cast<std::size_t>(printer.pixelsX) * static_cast<std::size_t>(printer.pixelsY), 0);
  for (std::size_t k = 0; k < placed.layers.size(); ++k) {
    const Image plate = displayRaster(placed.layers[k], printer);
    std::size_t white = 0;
    for (int r = 0; r < plate.height; ++r) {
      const std::uint8_t* row = plate.at(0, r);
      const std::size_t j = static_cast<std::size_t>(printer.pixelsY - 1 - r);
      for (int i = 0; i < plate.width; ++i) {
        if (row[i] == 0) continue;
        ++white;
        topLayer[static_cast<std::size_t>(i) + j * static_cast<std::size_t>(printer.pixelsX)] = static_cast<std::uint32_t>(k + 1);
      }
    }
    s.exposedArea.push_back(static_cast<double>(white) * p * p);
    const bool slow = static_cast<double>(white) > printer.areaFill / 100.0 * displayPixels;
    (slow ? s.numSlow : s.numFast) += 1;
    const double fade = static_cast<double>(options.fadeLayers);
    const double exposure = static_cast<double>(k) < fade
                                ? options.initialExposure + (options.exposure - options.initialExposure) * static_cast<double>(k) / fade
                                : options.exposure;
    s.printTime += exposure + (slow ? printer.slowTiltTime : printer.fastTiltTime);
    s.usedMaterial += s.exposedArea.back() * h / 1000.0;  // mm³ → ml
    char name[32];
    std::snprintf(name, sizeof name, "%05zu.png", k);
    entries.push_back({s.jobName + name, encodePng(transformed(plate, printer), ppm), false});
  }
  for (const auto& [w, th] : options.thumbnails) {
    entries.push_back({"thumbnail/thumbnail" + std::to_string(w) + "x" + std::to_string(th) + ".png",
                       encodePng(thumbnail(topLayer, s.layers, printer, w, th)), false});
  }
  const std::string version = std::string("duplexfit-") + DUPLEXFIT_VERSION_STRING;
  const std::string config = ini({{"action", "print"},
                                  {"expTime", num(options.exposure)},
                                  {"expTimeFirst", num(options.initialExposure)},
                                  {"expUserProfile", "0"},
                                  {"fileCreationTimestamp", utcTimestamp()},
                                  {"hollow", options.hollow ? "1" : "0"},
                                  {"jobDir", s.jobName},
                                  {"layerHeight", num(h)},
                                  {"materialName", options.materialName},
                                  {"numFade", std::to_string(options.fadeLayers)},
                                  {"numFast", std::to_string(s.numFast)},
                                  {"numSlow", std::to_string(s.numSlow)},
                                  {"printProfile", options.printProfile},
                                  {"printTime", num(std::round(s.printTime * 1000.0) / 1000.0)},
                                  {"printerModel", printer.model},
                                  {"printerProfile", printer.profile},
                                  {"printerVariant", printer.variant},
                                  {"prusaSlicerVersion", version},
                                  {"usedMaterial", num(std::round(s.usedMaterial * 1e6) / 1e6)}});
  std::string thumbs;
  for (const auto& [w, th] : options.thumbnails) thumbs += (thumbs.empty() ? "" : ",") + std::to_string(w) + "x" + std::to_string(th);
  const std::string W = num(printer.displayWidth), D = num(printer.displayHeight);
  const std::string settings = ini({{"area_fill", num(printer.areaFill)},
                                    {"bed_shape", "0x0," + W + "x0," + W + "x" + D + ",0x" + D},
                                    {"display_height", D},
                                    {"display_mirror_x", printer.mirrorX ? "1" : "0"},
                                    {"display_mirror_y", printer.mirrorY ? "1" : "0"},
                                    {"display_orientation", sl1OrientationName(printer.orientation)},
                                    {"display_pixels_x", std::to_string(printer.pixelsX)},
                                    {"display_pixels_y", std::to_string(printer.pixelsY)},
                                    {"display_width", W},
                                    {"exposure_time", num(options.exposure)},
                                    {"faded_layers", std::to_string(options.fadeLayers)},
                                    {"fast_tilt_time", num(printer.fastTiltTime)},
                                    {"gamma_correction", "0"},  // binary masks: no antialiasing
                                    {"hollowing_enable", "0"},  // duplexfit's own shell, not PrusaSlicer's
                                    {"initial_exposure_time", num(options.initialExposure)},
                                    {"initial_layer_height", num(h)},
                                    {"layer_height", num(h)},
                                    {"max_print_height", num(printer.maxPrintHeight)},
                                    {"pad_enable", "0"},
                                    {"printer_model", printer.model},
                                    {"printer_settings_id", printer.profile},
                                    {"printer_technology", "SLA"},
                                    {"printer_variant", printer.variant},
                                    {"sla_material_settings_id", options.materialName},
                                    {"sla_print_settings_id", options.printProfile},
                                    {"slow_tilt_time", num(printer.slowTiltTime)},
                                    {"supports_enable", "0"},
                                    {"thumbnails", thumbs}});
  entries[0] = {"config.ini", std::vector<std::uint8_t>(config.begin(), config.end()), true};
  entries[1] = {"prusaslicer.ini", std::vector<std::uint8_t>(settings.begin(), settings.end()), true};
  for (const Entry& e : entries) s.entries.push_back(e.name);
#ifdef DUPLEXFIT_HAVE_LIBZIP
  const std::vector<std::uint8_t> bytes = zipArchive(entries, path);
  s.bytes = bytes.size();
  AtomicFile out(path);
  out.write(bytes.data(), bytes.size());
  out.commit();
#endif
  return s;
}

}  // namespace duplexfit
