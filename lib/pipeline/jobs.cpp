// The jobs of measure, check, denoise, normals, section and slice (jobs.hpp): reading the inputs, running
// the library's operations, the progress lines, and the output files of section and slice. Their reports
// are written in jobs_json.cpp.
#include "duplexfit/jobs.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <sstream>
#include <utility>

#include <unistd.h>

#include "duplexfit/error.hpp"
#include "duplexfit/image.hpp"
#include "duplexfit/io.hpp"

namespace duplexfit {

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

void log(Interrupter* i, const std::string& line) {
  if (i) i->message(line);
}

std::string num(double v, int precision) {
  std::ostringstream s;
  s << std::setprecision(precision) << v;
  return s.str();
}

/// Opens the job's precision on `device` and builds its kernels (timed apart from the stages).
double buildKernels(const Device& device, Precision precision, Interrupter* interrupter) {
  device.requirePrecision(precision);
  const Clock::time_point t = Clock::now();
  device.compileKernels(precision);
  const double seconds = since(t);
  log(interrupter, "device: " + device.description());
  return seconds;
}

/// Reads a cloud, normals optional (each job decides what it needs).
PointCloudFile readCloud(const std::string& path, CloudJobInfo& info) {
  const Clock::time_point t = Clock::now();
  PointReadOptions ro;
  ro.requireNormals = false;
  PointCloudFile file = readPointCloudWithReport(path, ro);
  info.secondsRead = since(t);
  info.input = path;
  info.inputHadNormals = file.report.normals;
  return file;
}

CloudJobInfo cloudInfo(const Device& device, Precision precision) {
  CloudJobInfo info;
  info.deviceSpec = device.info().spec;
  info.deviceName = device.info().name;
  info.precision = precision;
  return info;
}

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

std::string layerName(std::size_t i, const char* ext) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "layer_%05zu.%s", i + 1, ext);
  return buf;
}

}  // namespace

// ---- measure and check -------------------------------------------------------------------------------

MeasuredMesh loadMeasuredMesh(const std::string& path, Interrupter* interrupter) {
  MeasuredMesh m;
  m.path = path;
  m.mesh = readMesh(path);
  m.validation = validateMesh(m.mesh, path);
  if (m.validation.degenerateFaces() > 0) {
    log(interrupter, path + ": " + std::to_string(m.validation.degenerateFaces()) + " degenerate triangles (first: face " +
                         std::to_string(m.validation.firstDegenerateFace) + ")");
  }
  return m;
}

DistanceJobResult runDistanceJob(const std::string& pathA, const std::string& pathB, const MeasureOptions& options,
                                 Interrupter* interrupter) {
  const Clock::time_point t = Clock::now();
  DistanceJobResult r;
  r.options = options;
  r.a = loadMeasuredMesh(pathA, interrupter);
  r.b = loadMeasuredMesh(pathB, interrupter);
  if (interrupter) interrupter->start("measure");
  r.report = measureDistance(r.a.mesh, r.b.mesh, options, interrupter);
  if (interrupter) interrupter->end();
  r.seconds = since(t);
  log(interrupter, "measured " + std::to_string(r.report.forward.samples + r.report.backward.samples) +
                       " samples in " + num(r.seconds, 3) + " s");
  return r;
}

OffsetJobResult runOffsetJob(const std::string& offsetPath, const std::string& surfacePath, double delta,
                             const MeasureOptions& options, Interrupter* interrupter) {
  if (delta == 0.0) throw InvalidArgument("measuring an offset needs the signed offset delta (non-zero)");
  const Clock::time_point t = Clock::now();
  OffsetJobResult r;
  r.delta = delta;
  r.options = options;
  r.offset = loadMeasuredMesh(offsetPath, interrupter);
  r.surface = loadMeasuredMesh(surfacePath, interrupter);
  if (interrupter) interrupter->start("measure");
  r.report = measureOffset(r.offset.mesh, r.surface.mesh, delta, options, interrupter);
  if (interrupter) interrupter->end();
  r.seconds = since(t);
  log(interrupter, "measured " + std::to_string(r.report.samples) + " samples in " + num(r.seconds, 3) + " s");
  return r;
}

CheckJobResult runCheckJob(const std::string& path, const CheckOptions& options, Interrupter* interrupter) {
  const Clock::time_point t = Clock::now();
  CheckJobResult r;
  r.mesh = loadMeasuredMesh(path);
  r.check = checkMesh(r.mesh.mesh, options);
  r.seconds = since(t);
  log(interrupter, "checked in " + num(r.seconds, 3) + " s");
  return r;
}

// ---- denoise and normals -------------------------------------------------------------------------------

DenoiseJobResult runDenoiseJob(const Device& device, const std::string& inputPath, const BilateralOptions& options,
                               Interrupter* interrupter) {
  const Clock::time_point start = Clock::now();
  DenoiseJobResult r;
  r.info = cloudInfo(device, options.precision);
  r.info.secondsKernelBuild = buildKernels(device, options.precision, interrupter);
  const PointCloudFile file = readCloud(inputPath, r.info);
  if (!file.report.normals) {
    throw InvalidArgument(inputPath + ": the cloud has no normals; the bilateral filter projects onto the tangent "
                                      "planes they define (run `duplexfit normals " +
                          inputPath + " -o WITH_NORMALS.ply` first)");
  }
  log(interrupter, "read " + std::to_string(file.points.size()) + " points from " + inputPath);
  if (interrupter && interrupter->wasInterrupted()) throw Cancelled("cancelled before denoise");
  BilateralResult filtered = bilateralFilter(device, file.points, options, interrupter);
  r.points = std::move(filtered.points);
  r.report = filtered.report;
  const BilateralReport& rep = r.report;
  log(interrupter, "filtered: sigma_s " + std::to_string(rep.sigmaSpatial) + ", sigma_r " +
                       std::to_string(rep.sigmaRange) + ", radius " + std::to_string(rep.radius) + ", " +
                       std::to_string(rep.meanNeighbors) + " neighbours a point, " + std::to_string(rep.seconds) +
                       " s");
  r.info.secondsTotal = since(start);
  return r;
}

NormalsJobResult runNormalsJob(const Device& device, const std::string& inputPath, const NormalOptions& options,
                               bool keepExisting, Interrupter* interrupter) {
  const Clock::time_point start = Clock::now();
  NormalsJobResult r;
  r.info = cloudInfo(device, options.precision);
  r.info.secondsKernelBuild = buildKernels(device, options.precision, interrupter);
  const PointCloudFile file = readCloud(inputPath, r.info);
  log(interrupter, "read " + std::to_string(file.points.size()) + " points from " + inputPath +
                       (file.report.normals ? " (with normals)" : " (no normals)"));
  if (keepExisting && file.report.normals) {
    r.points = file.points;
    r.keptExisting = true;
    log(interrupter, "kept the input's normals (--keep-existing)");
    r.info.secondsTotal = since(start);
    return r;
  }
  if (interrupter && interrupter->wasInterrupted()) throw Cancelled("cancelled before normals");
  try {
    NormalResult estimated = estimateNormals(device, file.points.positions(), options, interrupter);
    r.points = std::move(estimated.points);
    r.report = estimated.report;
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(inputPath + ": " + e.what());
  }
  const NormalReport& rep = r.report;
  log(interrupter, "estimated normals: k " + std::to_string(rep.k) + ", " + std::to_string(rep.components) +
                       " component(s), " + std::to_string(rep.flippedComponents) + " flipped outward, " +
                       std::to_string(rep.degenerate) + " degenerate, " + std::to_string(rep.seconds) + " s");
  if (rep.ambiguousComponents > 0) {
    log(interrupter, "warning: " + std::to_string(rep.ambiguousComponents) +
                         " component(s) enclose no volume: their normals are consistent but not necessarily outward");
  }
  if (file.report.normals) {
    std::size_t with = 0, agree = 0;
    for (Eigen::Index i = 0; i < r.points.positions().rows(); ++i) {
      if (file.points.normals().row(i).squaredNorm() == 0.0) continue;
      ++with;
      agree += r.points.normals().row(i).dot(file.points.normals().row(i)) > 0.0 ? 1 : 0;
    }
    if (with > 0) r.agreeingWithInput = static_cast<double>(agree) / static_cast<double>(with);
  }
  r.info.secondsTotal = since(start);
  return r;
}

double writeCloudOutput(const std::string& path, const PointSet& points) {
  const Clock::time_point t = Clock::now();
  writePointCloud(path, points);
  return since(t);
}

// ---- section -------------------------------------------------------------------------------------------

std::vector<SectionPlane> sectionCentrePlanes(const ImplicitField& field) {
  std::vector<SectionPlane> planes;
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
  return planes;
}

SectionJob prepareSectionJob(const std::string& fieldPath, const SectionJobOptions& options) {
  const Clock::time_point start = Clock::now();
  SectionJob job;
  job.fieldPath = fieldPath;
  job.options = options.section;
  job.field = ImplicitField::load(fieldPath);
  job.planes = options.plane ? std::vector<SectionPlane>{*options.plane} : sectionCentrePlanes(job.field);
  if (!options.pointsPath.empty()) {
    PointReadOptions read;
    read.requireNormals = false;
    job.options.points = readPointCloud(options.pointsPath, read).positions();
    job.points = true;
  }
  for (const SectionPlane& p : job.planes) validateSection(job.field, p, job.options);  // before the device work
  const std::string& output = options.output;
  if (output.empty()) throw InvalidArgument("section needs an output file or folder");
  const bool folder = fs::is_directory(output) || output.back() == '/';
  for (const SectionPlane& p : job.planes) {
    const std::string axis = sectionAxisName(p.axis);
    if (folder) {
      job.files.push_back((fs::path(output) / ("section_" + axis + ".png")).string());
    } else if (!options.plane) {
      job.files.push_back((endsWithPng(output) ? output.substr(0, output.size() - 4) : output) + "_" + axis + ".png");
    } else {
      job.files.push_back(output);
    }
  }
  job.secondsPrepare = since(start);
  return job;
}

SectionJobResult runSectionJob(const Device& device, const SectionJob& job, Interrupter* interrupter) {
  const Clock::time_point start = Clock::now();
  const ImplicitField& field = job.field;
  SectionJobResult out;
  out.files = job.files;
  out.deviceSpec = device.info().spec;
  out.deviceName = device.info().name;
  out.precision = job.options.precision;
  out.points = job.points;
  log(interrupter, "field " + job.fieldPath + ": " + std::to_string(field.levels().size()) + " levels, " +
                       std::to_string(field.centreCount()) + " centres, " + std::to_string(field.offsets().size()) +
                       " offset(s)");
  Clock::time_point t = Clock::now();
  const FieldEvaluator evaluator(device, field, job.options.precision);
  out.secondsSetup = since(t);

  PendingFiles pending;
  for (std::size_t i = 0; i < job.planes.size(); ++i) {
    if (interrupter && interrupter->wasInterrupted(static_cast<int>(100 * i / job.planes.size()))) {
      throw Cancelled("section: cancelled after " + std::to_string(i) + " planes");
    }
    SectionResult r = renderSection(evaluator, field, job.planes[i], job.options);
    t = Clock::now();
    try {
      writePng(pending.add(job.files[i]), r.image);
    } catch (const IoError& e) {
      throw IoError(job.files[i] + ": cannot write the image (" + e.what() + ")");
    }
    const double writeSeconds = since(t);
    std::ostringstream line;
    line << "section " << job.planes[i].toString() << ": " << r.image.width << "x" << r.image.height << " px, "
         << r.seconds << " s (+ " << writeSeconds << " s PNG)";
    log(interrupter, line.str());
    r.image.pixels = std::vector<std::uint8_t>();  // keep only the summary
    r.values = std::vector<float>();
    out.sections.push_back(std::move(r));
  }
  pending.commit();
  out.secondsTotal = job.secondsPrepare + since(start);
  return out;
}

// ---- slice ---------------------------------------------------------------------------------------------

namespace {

/// The job's slicer: the field itself, or with drain holes the drained solid min(f, δ − f, holes) sliced
/// as a zero-mode function (its derivatives those of the active piece, for the adaptive thickness).
Slicer makeSlicer(const Device& device, const ImplicitField& field, const SliceJobOptions& options) {
  const SliceOptions& o = options.slice;
  if (options.drainHoles.empty()) return Slicer(device, field, o);
  if (o.mode != SliceMode::Shell) throw InvalidArgument("--drain-hole needs --mode shell (holes drain a cavity)");
  const std::vector<double>& offsets = field.offsets();
  if (o.offsetIndex < 0 || o.offsetIndex >= static_cast<int>(offsets.size())) {
    throw InvalidArgument("--offset-index " + std::to_string(o.offsetIndex) + " is out of range (the field has " +
                          std::to_string(offsets.size()) + " offsets)");
  }
  const double delta = offsets[static_cast<std::size_t>(o.offsetIndex)];
  if (!(delta > 0.0)) {
    throw InvalidArgument("--drain-hole needs an inward offset (delta > 0); offset " + std::to_string(o.offsetIndex) +
                          " of the field is " + num(delta, 6));
  }
  for (const DrainHole& h : options.drainHoles) {
    if (!h.point.allFinite() || !(h.radius > 0.0) || !std::isfinite(h.radius)) {
      throw InvalidArgument("--drain-hole: the point must be finite and the radius > 0");
    }
  }
  const auto evaluator = std::make_shared<const FieldEvaluator>(device, field, o.precision);
  FieldFunction drained = [evaluator, delta, holes = options.drainHoles](const Points& q, FieldDerivatives d) {
    return drainedShellSamples(q, evaluator->evaluate(q, d), delta, holes);
  };
  SliceOptions zero = o;
  zero.mode = SliceMode::Zero;
  return Slicer(std::move(drained), field.bounds(), offsets, zero);
}

/// The SLA package's requirements (before slicing): libzip, a plain .sl1 name, uniform layers, mm, plate
/// placement, a plate that is the display, a part's box (size `part`, height `height`, mm) that fits it.
void checkSl1Job(const SliceJobOptions& options, const SliceOptions& used, double height, const Eigen::Vector2d& part) {
  const std::string& name = options.sl1;
  if (!sl1Available()) {
    throw InvalidArgument("--sl1 " + name + ": this build of duplexfit has no libzip (Debian: libzip-dev), so it "
                          "cannot write SL1 packages; rebuild with libzip-dev installed");
  }
  std::string lower = name;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const bool extension = (lower.size() > 4 && lower.compare(lower.size() - 4, 4, ".sl1") == 0) ||
                         (lower.size() > 5 && lower.compare(lower.size() - 5, 5, ".sl1s") == 0);
  if (fs::path(name).filename().string() != name || !extension) {
    throw InvalidArgument("--sl1 " + name + ": give a file name ending in .sl1 (or .sl1s), without a folder; the "
                          "package is written in the output folder (-o DIR)");
  }
  validateSl1Options(options.sl1Options);
  if (!(used.layer > 0.0)) {
    throw InvalidArgument("--sl1 " + name + ": an SL1 package has one layer height; slice with uniform layers "
                          "(--layer H, in model units) instead of adaptive ones (--cusp)");
  }
  if (options.unitsName != "mm" || options.units != 1.0) {
    throw InvalidArgument("--sl1 " + name + ": the package is in millimetres; use --units mm (the default) and "
                          "--scale S to bring the model to millimetres");
  }
  if (options.placement.place != SlicePlace::Plate) {
    throw InvalidArgument("--sl1 " + name + ": the part must be placed on the plate (--place plate, the default)");
  }
  const Sl1Printer& printer = options.sl1Options.printer;
  const Eigen::Vector2d display(printer.displayWidth, printer.displayHeight);
  const Eigen::Vector2d& plate = options.placement.plate;
  if ((plate.x() != 0.0 || plate.y() != 0.0) && (plate - display).cwiseAbs().maxCoeff() > 1e-9 * display.maxCoeff()) {
    throw InvalidArgument("--plate " + num(plate.x(), 6) + "x" + num(plate.y(), 6) + " with --sl1: the plate is the "
                          "printer's display (" + num(display.x(), 6) + "x" + num(display.y(), 6) +
                          " mm, --sl1-display); leave --plate out");
  }
  if (part.x() > display.x() || part.y() > display.y()) {
    throw InvalidArgument("--sl1 " + name + ": the part's box (" + num(part.x(), 6) + " x " + num(part.y(), 6) +
                          " mm) is larger than the printer's display (" + num(display.x(), 6) + " x " +
                          num(display.y(), 6) + " mm, --sl1-display); scale it down (--scale) or turn it (--axis)");
  }
  if (height > printer.maxPrintHeight + used.layer) {
    throw InvalidArgument("--sl1 " + name + ": the part is " + num(height, 6) + " mm tall, more than the printer's " +
                          num(printer.maxPrintHeight, 6) + " mm");
  }
}

}  // namespace

SliceJob::SliceJob(const Device& device, const ImplicitField& field, const SliceJobOptions& options, std::string input)
    : slicer_(makeSlicer(device, field, options)),
      options_(options),
      input_(std::move(input)),
      deviceSpec_(device.info().spec),
      start_(Clock::now()) {
  const SliceOptions& used = slicer_.options();
  options_.slice = used;
  options_.slice.mode = options.slice.mode;  // drain holes slice the drained solid as a zero-mode function
  const double pixel = options.maskPixel;
  PlacementOptions& place = options_.placement;
  const double s = place.scale;
  if (!(s > 0.0) || !std::isfinite(s)) throw InvalidArgument("--scale must be > 0 (got " + num(s, 6) + ")");
  if (!(options.units > 0.0) || !std::isfinite(options.units)) {
    throw InvalidArgument("--units: " + num(options.units, 6) + " millimetres per unit (must be > 0)");
  }
  const bool plateGiven = place.plate.x() != 0.0 || place.plate.y() != 0.0;
  if (plateGiven && !(place.plate.x() > 0.0 && place.plate.y() > 0.0 && place.plate.allFinite())) {
    throw InvalidArgument("--plate must be two positive sizes WxD (got " + num(place.plate.x(), 6) + "x" +
                          num(place.plate.y(), 6) + ")");
  }
  if (plateGiven && place.place == SlicePlace::None) throw InvalidArgument("--plate needs --place plate");
  if (pixel != 0.0 && !(pixel > 0.0 && std::isfinite(pixel))) throw InvalidArgument("--png-xy must be > 0");
  place.plateStep = pixel > 0.0 ? pixel : 0.0;
  // Fail before slicing when the part's box clearly exceeds the plate (the loops are checked after
  // slicing) or the masks cannot be made.
  const Eigen::Vector3d size = slicer_.bounds().sizes();
  const Eigen::Vector2d part = s * Eigen::Vector2d(size[(used.axis + 1) % 3], size[(used.axis + 2) % 3]);
  const double margin = 4.0 * used.grid * s;
  if (!options.sl1.empty()) {
    checkSl1Job(options, used, s * size[used.axis], part);
    options_.sl1Options.hollow = options.slice.mode == SliceMode::Shell;
    const Sl1Printer& printer = options.sl1Options.printer;
    place.plate = Eigen::Vector2d(printer.displayWidth, printer.displayHeight);  // the plate is the display
    place.plateStep = 0.0;
    if (pixel > 0.0 && (place.plate.x() / pixel > 65536.0 || place.plate.y() / pixel > 65536.0)) {
      throw InvalidArgument("--png-xy " + num(pixel, 6) + " gives masks larger than 65536 pixels a side");
    }
    // One layer image at a time at the display's resolution (8-bit, its PNG and the zip's buffers), and the masks.
    const double displayPixels = static_cast<double>(printer.pixelsX) * static_cast<double>(printer.pixelsY);
    const double maskPixels = pixel > 0.0 ? (place.plate.x() / pixel) * (place.plate.y() / pixel) : 0.0;
    requireMemory(used.limits, "slice", 4.0 * (displayPixels + maskPixels),
                  "the " + std::to_string(printer.pixelsX) + " x " + std::to_string(printer.pixelsY) + " SL1 layer images",
                  "use fewer --sl1-pixels or a larger --png-xy");
    return;  // the part's box was checked against the display
  }
  if (plateGiven && (part.x() > place.plate.x() + margin || part.y() > place.plate.y() + margin)) {
    throw InvalidArgument("--plate " + num(place.plate.x(), 6) + "x" + num(place.plate.y(), 6) + ": the part's box (" +
                          num(part.x(), 6) + " x " + num(part.y(), 6) + ") is larger than the plate");
  }
  if (pixel > 0.0) {
    const Eigen::Vector2d area = plateGiven ? place.plate : Eigen::Vector2d(part.array() + margin);
    if (area.x() / pixel > 65536.0 || area.y() / pixel > 65536.0) {
      throw InvalidArgument("--png-xy " + num(pixel, 6) + " gives masks larger than 65536 pixels a side");
    }
    // One mask at a time: the 8-bit image, its PNG rows and compression buffers.
    const double pixels = (area.x() / pixel) * (area.y() / pixel);
    requireMemory(used.limits, "slice", 4.0 * pixels,
                  "a " + num(area.x() / pixel, 6) + " x " + num(area.y() / pixel, 6) + " pixel PNG mask (--png-xy " +
                      num(pixel, 6) + ")",
                  "use a larger --png-xy");
  }
}

SliceJobResult SliceJob::run(Interrupter* interrupter) const {
  const SliceOptions& used = options_.slice;
  log(interrupter, std::string("slicing ") + input_ + " along " + "xyz"[used.axis] + ", mode " +
                       sliceModeName(used.mode) +
                       (used.layer > 0.0 ? ", uniform layers " + std::to_string(used.layer)
                                         : ", cusp " + std::to_string(used.cusp) + ", layers " +
                                               std::to_string(used.minLayer) + " to " + std::to_string(used.maxLayer)) +
                       ", grid " + std::to_string(used.grid) + ", heights " + std::to_string(used.start) + " to " +
                       std::to_string(used.end));
  SliceJobResult r;
  r.input = input_;
  r.deviceSpec = deviceSpec_;
  r.options = options_;
  const Clock::time_point t = Clock::now();
  if (!options_.drainHoles.empty()) {
    log(interrupter, std::to_string(options_.drainHoles.size()) +
                         " drain hole(s): slicing the drained solid min(f, delta - f, hole distances)");
  }
  r.slices = slicer_.run(interrupter);
  r.slices.mode = used.mode;
  r.secondsSlice = since(t);
  try {
    r.placement = placeSlices(r.slices, options_.placement);  // InvalidArgument: the part does not fit the plate
  } catch (const InvalidArgument& e) {
    if (options_.sl1.empty()) throw;
    throw InvalidArgument("--sl1 " + options_.sl1 + " (the plate is the printer's display, --sl1-display): " + e.what());
  }
  r.placed = applyPlacement(r.slices, r.placement);
  const Eigen::Vector3d& tr = r.placement.translation;
  const Eigen::Vector2d plate = r.placement.plate.sizes();
  log(interrupter, std::string("placement ") + slicePlaceName(r.placement.place) + ": scale " +
                       num(r.placement.scale, 6) + ", translation (" + num(tr.x(), 6) + ", " + num(tr.y(), 6) + ", " +
                       num(tr.z(), 6) + ") " + options_.unitsName + ", plate " + num(plate.x(), 6) + " x " +
                       num(plate.y(), 6) + " " + options_.unitsName);
  for (const SliceLayer& l : r.slices.layers) r.layersTouchingBorder += l.touchesBoundary ? 1 : 0;
  if (r.layersTouchingBorder > 0) {
    log(interrupter, "warning: in " + std::to_string(r.layersTouchingBorder) +
                         " layer(s) a level set reached the padded grid border; loops were closed there");
  }
  r.secondsTotal = since(start_);
  return r;
}

SliceJobResult runSliceJob(const Device& device, const ImplicitField& field, const SliceJobOptions& options,
                           const std::string& input, Interrupter* interrupter) {
  return SliceJob(device, field, options, input).run(interrupter);
}

SliceMaskInfo sliceMaskInfo(const SliceJobResult& result) {
  SliceMaskInfo m;
  m.pixel = result.options.maskPixel;
  if (!(m.pixel > 0.0)) return m;
  const Eigen::AlignedBox2d& plate = result.placement.plate;
  const Eigen::Vector2d n = maskPixels(plate, m.pixel);
  if (!(n.x() >= 1.0 && n.y() >= 1.0) || n.x() > 65536.0 || n.y() > 65536.0) {
    throw InvalidArgument("--png-xy " + num(m.pixel, 6) + " gives " + num(n.x(), 8) + " x " + num(n.y(), 8) +
                          " pixel masks (1 to 65536 pixels a side)");
  }
  m.width = static_cast<int>(n.x());
  m.height = static_cast<int>(n.y());
  m.origin = Eigen::Vector2d(plate.min().x(), plate.max().y());
  m.area = Eigen::AlignedBox2d(Eigen::Vector2d(m.origin.x(), m.origin.y() - n.y() * m.pixel),
                               Eigen::Vector2d(m.origin.x() + n.x() * m.pixel, m.origin.y()));
  const double perMetre = 1000.0 / (m.pixel * result.options.units);  // pixel · units = mm per pixel
  m.dpi = 0.0254 * perMetre;
  const double rounded = std::round(perMetre);
  m.pixelsPerMetre = rounded >= 1.0 && rounded <= 2147483647.0 ? static_cast<std::uint32_t>(rounded) : 0u;
  return m;
}

SliceOutputs writeSliceOutputs(const SliceJobResult& result, StagedFolder& staging) {
  SliceOutputs out;
  const Clock::time_point t = Clock::now();
  const SliceResult& slices = result.placed;  // output coordinates, output units
  writeCli(staging.path("slices.cli"), slices, result.options.units, result.options.units);
  if (result.options.svgPerLayer) {
    const std::string dir = staging.path("svg", true);
    for (std::size_t i = 0; i < slices.layers.size(); ++i) {
      writeSliceSvg((fs::path(dir) / layerName(i, "svg")).string(), slices, static_cast<int>(i));
    }
  } else {
    writeSliceSvg(staging.path("slices.svg"), slices);
  }
  const double pixel = result.options.maskPixel;
  if (pixel > 0.0) {
    const std::string dir = staging.path("masks", true);
    const SliceMaskInfo mask = sliceMaskInfo(result);
    for (std::size_t i = 0; i < slices.layers.size(); ++i) {
      const Image img = rasterizeLayer(slices.layers[i], mask.area, pixel);
      std::size_t white = 0;
      for (std::uint8_t p : img.pixels) white += p != 0 ? 1 : 0;
      out.maskArea.push_back(static_cast<double>(white) * pixel * pixel);
      writePng((fs::path(dir) / layerName(i, "png")).string(), img, mask.pixelsPerMetre);
    }
  }
  if (!result.options.sl1.empty()) {
    out.sl1 = writeSl1(staging.path(result.options.sl1), slices, result.options.sl1Options);
  }
  out.secondsWrite = since(t);
  std::ostringstream report;
  writeSliceJson(report, result, out.maskArea, out.secondsWrite, out.sl1 ? &*out.sl1 : nullptr);
  out.report = report.str();
  {
    AtomicFile f(staging.path("slices.json"));
    f.write(out.report);
    f.commit();
  }
  staging.commit();
  return out;
}

}  // namespace duplexfit
