// `duplexfit section`: pictures of f on axis-aligned planes (blue outside, white at 0, red inside, with
// the 0-level and offset contours). Every image is written under a temporary name first and renamed
// into place only when all of them are done, so a failed run leaves no partial output.
#include <cctype>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "options.hpp"
#include "timer.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/image.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/section.hpp"

namespace duplexfit::cli {

const char* const kSectionHelp =
    R"(  section FIELD      picture of f on an axis-aligned plane: blue outside (f < 0), white at 0, red inside,
                     with the 0-level (black) and offset level (green, purple, ...) contour lines
      -o OUT.png       output; without --plane three planes through the box centre: OUT_x.png,
                       OUT_y.png, OUT_z.png (-o FOLDER: section_x.png, ... inside it)
      --plane x=C|y=C|z=C  one plane, in input units
      --size N         pixels along the longer side (16..16384, default 1024)
      --range R        colour scale ±R (default: the 99th percentile of |f| in the picture)
      --gamma G        colour intensity ∝ (|f|/R)^G (default 0.5; 1: linear)
      --rect U0,V0,U1,V1   the part of the plane shown, in (right, up) coordinates: (y, z) for x=C,
                       (x, z) for y=C, (x, y) for z=C (default: the field's box plus 5%)
      --points CLOUD   draw the cloud's points near the plane as yellow dots
      --band W         only points within W of the plane (default 1% of the box's longest side)
      --device SPEC, --precision float|double, --json (summary on stdout), --quiet
)";

namespace {

namespace fs = std::filesystem;

bool endsWithPng(const std::string& s) {
  if (s.size() < 4) return false;
  std::string ext = s.substr(s.size() - 4);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".png";
}

/// Images written under temporary names; commit() renames them all into place. Until then (and when a
/// rename fails) the destructor removes the temporary files and whatever was already moved.
class PendingFiles {
 public:
  PendingFiles() = default;
  PendingFiles(const PendingFiles&) = delete;
  PendingFiles& operator=(const PendingFiles&) = delete;
  ~PendingFiles() {
    if (committed_) return;
    std::error_code ec;
    for (const auto& [temp, final] : files_) fs::remove(temp, ec);
    for (const std::string& moved : moved_) fs::remove(moved, ec);
  }
  /// The temporary name for `path` (same folder, so that the rename stays on one file system).
  std::string add(const std::string& path) {
    files_.emplace_back(path + ".tmp-section-" + std::to_string(::getpid()), path);
    return files_.back().first;
  }
  void commit() {
    for (const auto& [temp, final] : files_) {
      std::error_code ec;
      fs::rename(temp, final, ec);
      if (ec) throw IoError(final + ": cannot move the image into place (" + ec.message() + ")");
      moved_.push_back(final);
    }
    committed_ = true;
  }

 private:
  std::vector<std::pair<std::string, std::string>> files_;
  std::vector<std::string> moved_;
  bool committed_ = false;
};

}  // namespace

int cmdSection(int argc, char** argv) {
  const Timer start;
  CLI::App app("picture of f on an axis-aligned plane", "section");
  bool quiet = false, json = false;
  DeviceOptions deviceOptions;
  SectionOptions options;
  std::string fieldPath, planeText, pointsPath, rectText, output;
  app.add_option("FIELD", fieldPath, "a field file (.dpxf)");
  app.add_option("-o,--output", output, "OUT.png, or a folder for the three axis planes")->type_name("OUT");
  app.add_option("--plane", planeText, "x=C, y=C or z=C (default: the three planes through the centre)");
  addInteger(app, "size", options.size, "pixels of the longer side (default 1024)");
  addNumber(app, "range", options.range, "|f| of full colour (default: from the field)");
  addNumber(app, "gamma", options.gamma, "colour gamma, in (0, 10]");
  app.add_option("--points", pointsPath, "overlay the cloud's points near the plane")->type_name("CLOUD");
  addNumber(app, "band", options.band, "distance from the plane of the points drawn (needs --points)");
  app.add_option("--rect", rectText, "U0,V0,U1,V1: the rectangle of the plane drawn");
  addDeviceOptions(app, deviceOptions);
  addQuiet(app, quiet);
  addJson(app, json);
  if (parse(app, argc, argv)) return 0;
  auto log = [quiet](const std::string& s) {
    if (!quiet) std::cerr << s << std::endl;
  };
  if (options.range < 0.0) throw UsageError("option --range must be positive");
  if (!(options.gamma > 0.0 && options.gamma <= 10.0)) throw UsageError("option --gamma must be in (0, 10]");
  if (options.band < 0.0) throw UsageError("option --band must be positive");
  if (options.band > 0.0 && pointsPath.empty()) throw UsageError("option --band needs --points CLOUD");
  options.precision = deviceOptions.precision;
  if (!rectText.empty()) {
    const std::vector<double> r = parseNumberList(rectText, "rect");
    if (r.size() != 4 || !(r[2] > r[0]) || !(r[3] > r[1])) {
      throw UsageError("option --rect needs U0,V0,U1,V1 with U1 > U0 and V1 > V0");
    }
    options.rectangle = Eigen::AlignedBox2d(Eigen::Vector2d(r[0], r[1]), Eigen::Vector2d(r[2], r[3]));
  }
  const std::string deviceSpec = deviceOptions.spec;
  if (fieldPath.empty()) throw UsageError("section needs a field file: duplexfit section FIELD -o OUT.png");
  if (output.empty()) throw UsageError("section needs an output: -o OUT.png (or -o FOLDER)");
  if (options.size < 16 || options.size > 16384) throw UsageError("option --size must be between 16 and 16384");

  std::vector<SectionPlane> planes;
  if (!planeText.empty()) planes.push_back(SectionPlane::parse(planeText));

  const ImplicitField field = ImplicitField::load(fieldPath);
  if (planes.empty()) {  // through the box centre, rounded to 1e-4 of the box's size for readable names
    const Eigen::Vector3d c = field.bounds().center();
    const double extent = field.bounds().sizes().maxCoeff();
    const double e = extent > 0.0 ? std::floor(std::log10(extent)) - 4.0 : 0.0;
    const double scale = std::pow(10.0, std::fabs(e));  // exact: |e| is small
    for (int axis = 0; axis < 3; ++axis) {
      // divide by the power of ten rather than multiply by its inverse: the nearest double to k·10^e
      double v = extent <= 0.0 ? c[axis] : e < 0.0 ? std::round(c[axis] * scale) / scale
                                                   : std::round(c[axis] / scale) * scale;
      if (!(v >= field.bounds().min()[axis] && v <= field.bounds().max()[axis])) v = c[axis];  // a flat box
      planes.push_back(SectionPlane{axis, v == 0.0 ? 0.0 : v});  // no "-0"
    }
  }
  if (!pointsPath.empty()) {
    PointReadOptions read;
    read.requireNormals = false;
    options.points = readPointCloud(pointsPath, read).positions();
  }

  for (const SectionPlane& p : planes) validateSection(field, p, options);  // before the device work

  // Output names.
  const bool folder = fs::is_directory(output) || output.back() == '/';
  std::vector<std::string> files;
  for (const SectionPlane& p : planes) {
    const std::string axis = sectionAxisName(p.axis);
    if (folder) {
      files.push_back((fs::path(output) / ("section_" + axis + ".png")).string());
    } else if (planeText.empty()) {
      files.push_back((endsWithPng(output) ? output.substr(0, output.size() - 4) : output) + "_" + axis + ".png");
    } else {
      files.push_back(output);
    }
  }

  const Device device = deviceSpec.empty() ? Device::openDefault() : Device::open(deviceSpec);
  log("device: " + device.description());
  log("field " + fieldPath + ": " + std::to_string(field.levels().size()) + " levels, " +
      std::to_string(field.centreCount()) + " centres, " + std::to_string(field.offsets().size()) + " offset(s)");
  Timer t;
  const FieldEvaluator evaluator(device, field, options.precision);
  const double setupSeconds = t.seconds();

  PendingFiles pending;
  std::vector<SectionResult> results;
  for (std::size_t i = 0; i < planes.size(); ++i) {
    SectionResult r = renderSection(evaluator, field, planes[i], options);
    t.restart();
    try {
      writePng(pending.add(files[i]), r.image);
    } catch (const IoError& e) {
      throw IoError(files[i] + ": cannot write the image (" + e.what() + ")");
    }
    const double writeSeconds = t.seconds();
    std::ostringstream line;
    line << "section " << planes[i].toString() << ": " << r.image.width << "x" << r.image.height << " px, "
         << r.seconds << " s (+ " << writeSeconds << " s PNG)";
    log(line.str());
    r.image.pixels = std::vector<std::uint8_t>();  // keep only the summary
    r.values = std::vector<float>();
    results.push_back(std::move(r));
  }
  pending.commit();
  const double totalSeconds = start.seconds();

  if (json) {
    using Json = nlohmann::ordered_json;
    Json sections = Json::array();
    for (std::size_t i = 0; i < results.size(); ++i) {
      const SectionResult& r = results[i];
      Json j{{"file", files[i]},
             {"plane", r.plane.toString()},
             {"width", r.image.width},
             {"height", r.image.height},
             {"pixel_size", r.pixelSize},
             {"axes", Json::array({sectionAxisName(r.plane.rightAxis()), sectionAxisName(r.plane.upAxis())})},
             {"rectangle", Json::array({r.rectangle.min().x(), r.rectangle.min().y(), r.rectangle.max().x(),
                                        r.rectangle.max().y()})},
             {"value_min", r.minValue},
             {"value_max", r.maxValue},
             {"range", r.range}};
      if (!pointsPath.empty()) {
        j["band"] = r.band;
        j["points_drawn"] = r.pointsDrawn;
      }
      j["seconds"] = r.seconds;
      sections.push_back(std::move(j));
    }
    const Json out{{"field", fieldPath},
                   {"device", device.info().spec},
                   {"device_name", device.info().name},
                   {"precision", precisionName(options.precision)},
                   {"files", files},
                   {"levels", results.front().levels},
                   {"sections", std::move(sections)},
                   {"setup_seconds", setupSeconds},
                   {"total_seconds", totalSeconds}};
    std::cout << out.dump(2, ' ', false, Json::error_handler_t::replace) << "\n";
    std::cout << "\n";
  } else {
    for (std::size_t i = 0; i < results.size(); ++i) {
      const SectionResult& r = results[i];
      std::cout << files[i] << ": " << r.plane.toString() << ", pixel " << r.pixelSize << ", f in [" << r.minValue
                << ", " << r.maxValue << "], colour scale ±" << r.range;
      if (!pointsPath.empty()) std::cout << ", " << r.pointsDrawn << " points within " << r.band;
      std::cout << "\n";
    }
  }
  return 0;
}

}  // namespace duplexfit::cli
