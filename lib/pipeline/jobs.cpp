// The jobs of measure, check, denoise, normals, section and slice (jobs.hpp): reading the inputs, running
// the library's operations, the progress lines, and the output files of section and slice. Their reports
// are written in jobs_json.cpp.
#include "duplexfit/jobs.hpp"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
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
  r.report = measureDistance(r.a.mesh, r.b.mesh, options);
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
  r.report = measureOffset(r.offset.mesh, r.surface.mesh, delta, options);
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
  BilateralReport& rep = r.report;
  r.points = bilateralFilter(file.points, options, device, &rep);
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
  NormalReport& rep = r.report;
  try {
    r.points = estimateNormals(file.points.positions(), options, device, &rep);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(inputPath + ": " + e.what());
  }
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

SliceJob::SliceJob(const Device& device, const ImplicitField& field, const SliceJobOptions& options, std::string input)
    : slicer_(device, field, options.slice),
      options_(options),
      input_(std::move(input)),
      deviceSpec_(device.info().spec),
      start_(Clock::now()) {
  const SliceOptions& used = slicer_.options();
  options_.slice = used;
  const double pixel = options.maskPixel;
  if (pixel != 0.0) {
    if (!(pixel > 0.0)) throw InvalidArgument("--png-xy must be > 0");
    // Fail before slicing when the masks cannot be made.
    const Eigen::Vector3d size = slicer_.bounds().sizes();
    const double w = (size[(used.axis + 1) % 3] + 4 * used.grid) / pixel;
    const double h = (size[(used.axis + 2) % 3] + 4 * used.grid) / pixel;
    if (w > 65536.0 || h > 65536.0) {
      throw InvalidArgument("--png-xy " + std::to_string(pixel) + " gives masks larger than 65536 pixels a side");
    }
  }
}

SliceJobResult SliceJob::run(Interrupter* interrupter) const {
  const SliceOptions& used = slicer_.options();
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
  r.slices = slicer_.run([interrupter](const SliceProgress& p) {
    if (!interrupter) return true;
    std::ostringstream line;
    line << "  layer " << p.layer << "  height " << std::setprecision(6) << p.height << "  thickness " << p.thickness
         << "  loops " << p.loops << "  (" << std::setprecision(3) << 100.0 * p.fraction << "%)";
    interrupter->message(line.str());
    return !interrupter->wasInterrupted(static_cast<int>(std::lround(100.0 * p.fraction)));
  });
  r.secondsSlice = since(t);
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

SliceOutputs writeSliceOutputs(const SliceJobResult& result, StagedFolder& staging) {
  SliceOutputs out;
  const Clock::time_point t = Clock::now();
  const SliceResult& slices = result.slices;
  writeCli(staging.path("slices.cli"), slices, result.options.units);
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
    const Eigen::AlignedBox2d box = planeBox(slices);
    for (std::size_t i = 0; i < slices.layers.size(); ++i) {
      const Image img = rasterizeLayer(slices.layers[i], box, pixel);
      std::size_t white = 0;
      for (std::uint8_t p : img.pixels) white += p != 0 ? 1 : 0;
      out.maskArea.push_back(static_cast<double>(white) * pixel * pixel);
      writePng((fs::path(dir) / layerName(i, "png")).string(), img);
    }
  }
  out.secondsWrite = since(t);
  std::ostringstream report;
  writeSliceJson(report, result, out.maskArea, out.secondsWrite);
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
