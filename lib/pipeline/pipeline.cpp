// runPipeline: the job of `duplexfit fit` (read, pre-process, fit, extract, self-check), the adaptation of
// an Interrupter to the per-operation progress callbacks, and runMeshPipeline (`duplexfit mesh`).
#include "duplexfit/pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <memory>
#include <sstream>
#include <utility>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

/// The Interrupter (or none) behind the per-operation callbacks, with the stage bookkeeping.
class Progress {
 public:
  explicit Progress(Interrupter* interrupter) : i_(interrupter) {}
  void log(const std::string& line) const {
    if (i_) i_->message(line);
  }
  /// Begins stage `name`, after a cancellation check.
  void start(const char* name) const {
    check(name);
    if (i_) i_->start(name);
  }
  void end() const {
    if (i_) i_->end();
  }
  void check(const char* before) const {
    if (i_ && i_->wasInterrupted()) throw Cancelled(std::string("cancelled before ") + before);
  }
  FitProgressCallback fit() const {
    if (!i_) return {};
    Interrupter* i = i_;
    return [i](const FitProgress& p) {
      i->fitEvent(p);
      const int percent = p.levels > 0 && p.level > 0 ? 100 * (p.level - 1) / p.levels : -1;
      return !i->wasInterrupted(percent);
    };
  }
  PolygonizeProgress polygonize() const {
    if (!i_) return {};
    Interrupter* i = i_;
    return [i](double fraction) { return !i->wasInterrupted(static_cast<int>(std::lround(100.0 * fraction))); };
  }

 private:
  Interrupter* i_;
};

std::string surfaceName(int surface) { return surface == 0 ? "zero level" : "offset " + std::to_string(surface); }

std::string formatBox(const Eigen::AlignedBox3d& box) {
  std::ostringstream s;
  s << std::setprecision(4) << "[" << box.min().x() << ", " << box.min().y() << ", " << box.min().z() << "] - ["
    << box.max().x() << ", " << box.max().y() << ", " << box.max().z() << "]";
  return s.str();
}

/// One warning line per component that failed the self-check, and per mesh that lost small components.
void logSelfCheck(const SelfCheckReport& r, const Progress& progress) {
  for (const SurfaceSelfCheck& s : r.surfaces) {
    if (s.dropped.components == 0) continue;
    std::ostringstream line;
    const double fraction = s.surface == 0 ? r.minAreaFraction : std::max(r.minAreaFraction, r.minOffsetAreaFraction);
    line << std::setprecision(4) << surfaceName(s.surface) << ": dropped " << s.dropped.components
         << " component(s) below " << fraction << " of the mesh's area (" << s.dropped.faces << " faces, "
         << 100.0 * s.dropped.areaFraction << "% of the area)";
    progress.log(line.str());
  }
  for (const ComponentIssue& i : r.issues) {
    std::ostringstream line;
    line << std::setprecision(4) << "warning: self-check: " << surfaceName(i.surface) << " component " << i.component
         << " (" << i.faces << " faces, area " << i.area << " = " << 100.0 * i.areaFraction << "% of the mesh, box "
         << formatBox(i.box) << ") ";
    if (i.why == ComponentIssue::Why::NoInputPoints) {
      line << "carries no input point (none within " << r.pointTolerance << "; the nearest is " << i.nearestInputPoint
           << " from its vertices)";
    } else {
      line << "is not on the offset: its vertices are " << i.meanDistance << " from the zero level on average, |delta| "
           << std::abs(i.iso) << " (mean deviation " << i.meanDeviation << ")";
    }
    progress.log(line.str());
  }
  std::ostringstream line;
  line << "self-check: " << r.issues.size() << " component issue(s), " << r.seconds << " s";
  progress.log(line.str());
}

/// Everything after the points are read: normals, merge, denoise, fit, surfaces, self-check, topology.
PipelineResult runOnPoints(const Device& device, PointCloudFile file, std::string inputName, double readSeconds,
                           const PipelineOptions& options, const Progress& progress, Clock::time_point start) {
  PipelineResult result;
  PipelineReport& report = result.report;
  report.input = std::move(inputName);
  report.secondsRead = readSeconds;
  const std::string& input = report.input;
  const std::string source = input.empty() ? std::string("points") : input;
  const FitOptions& fitOptions = options.fit;
  const Precision precision = fitOptions.precision;

  if (options.estimateNormals) {
    NormalOptions normalOptions = options.normals;
    normalOptions.precision = precision;
    NormalReport nr;
    progress.start("normals");
    progress.log(std::string(file.report.normals ? "re-estimating" : "estimating") + " normals (k = " +
                 std::to_string(normalOptions.k) + ") ...");
    try {
      file.points = estimateNormals(file.points.positions(), normalOptions, device, &nr);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(source + ": " + e.what());
    }
    progress.log("normals: " + std::to_string(nr.components) + " component(s), " +
                 std::to_string(nr.flippedComponents) + " flipped outward, " + std::to_string(nr.seconds) + " s");
    progress.end();
    report.normals = nr;
  }
  report.duplicatesMerged = file.points.mergeDuplicates();
  if (options.denoise) {
    BilateralOptions filter = options.denoiseOptions;
    filter.precision = precision;
    BilateralReport br;
    progress.start("denoise");
    progress.log("bilateral filter ...");
    file.points = bilateralFilter(file.points, filter, device, &br);
    progress.log("bilateral filter: sigma_s " + std::to_string(br.sigmaSpatial) + ", sigma_r " +
                 std::to_string(br.sigmaRange) + ", mean displacement " + std::to_string(br.meanDisplacement) + ", " +
                 std::to_string(br.seconds) + " s");
    progress.end();
    report.denoise = br;
  }
  checkFittable(file.points, source);  // errors name the file
  progress.log("read " + std::to_string(file.report.points) + " points from " + input + " (" +
               std::to_string(report.duplicatesMerged) + " duplicates merged) in " + std::to_string(report.secondsRead) +
               " s");
  report.read = file.report;
  report.separate = options.separate;
  report.sideTest = fitOptions.sideTest;

  // Duplex mode: one field, every surface a level set of it. Separate mode: one field per surface, each
  // surface the 0-level of its own field (the baseline of the paper's Table 1).
  progress.start("fit");
  FitReport& rep = report.fit;
  std::shared_ptr<const FieldEvaluator> evaluator;  // the duplex fit's, reused by the extraction
  if (options.separate) {
    SeparateFitResult sep = fitSeparate(device, file.points, fitOptions, progress.fit());
    rep = sep.zeroReport;
    rep.offsets = sep.offsetDeltas;
    rep.secondsTotal = sep.secondsTotal;
    for (const FitReport& r : sep.offsetReports) rep.eDelta.push_back(r.e0);  // each at its own points
    report.separateFits.push_back(std::move(sep.zeroReport));
    report.separateFittedPoints.push_back(file.points.size());
    for (std::size_t j = 0; j < sep.offsets.size(); ++j) {
      report.separateFits.push_back(std::move(sep.offsetReports[j]));
      report.separateFittedPoints.push_back(sep.offsetPoints[j]);
    }
    result.fields.push_back(std::move(sep.zero));
    for (ImplicitField& f : sep.offsets) result.fields.push_back(std::move(f));
  } else {
    FitResult fitted = fit(device, file.points, fitOptions, progress.fit());
    rep = std::move(fitted.report);
    result.fields.push_back(std::move(fitted.field));
    evaluator = std::move(fitted.evaluator);
  }
  rep.duplicatesMerged = report.duplicatesMerged;
  progress.end();
  const auto warnUnconverged = [&](const FitReport& r) {
    for (const LevelReport& l : r.levelReports) {
      if (l.solve.iterations > 0 && !l.solve.converged) {
        progress.log("warning: level " + std::to_string(l.level) + " CG did not converge (" +
                     stopReasonName(l.solve.reason) + ", residual " + std::to_string(l.solve.relativeResidual) + ")");
      }
    }
  };
  warnUnconverged(rep);
  for (std::size_t j = 1; j < report.separateFits.size(); ++j) warnUnconverged(report.separateFits[j]);

  auto t = Clock::now();
  std::vector<double> isos{0.0};
  isos.insert(isos.end(), rep.offsets.begin(), rep.offsets.end());
  progress.start("polygonize");
  progress.log("polygonizing " + std::to_string(isos.size()) + " level sets ...");
  SurfaceOptions surface = options.surface;
  surface.precision = precision;
  std::vector<SurfaceResult> extracted;
  std::vector<Mesh> meshes;
  if (!options.separate) {
    extracted.push_back(evaluator ? extractSurfaces(*evaluator, result.fields[0], isos, surface, progress.polygonize())
                                  : extractSurfaces(device, result.fields[0], isos, surface, progress.polygonize()));
    meshes = std::move(extracted.back().meshes);
  } else {
    // The separate fields share the zero field's grid cell unless the user chose one, so that both modes
    // mesh at the same resolution.
    if (surface.cell <= 0.0 && surface.resolution <= 0) {
      surface.cell = surfaceGrid(result.fields[0], isos, surface).cellSize().maxCoeff();
    }
    for (const ImplicitField& f : result.fields) {
      extracted.push_back(extractSurfaces(device, f, {0.0}, surface, progress.polygonize()));
      meshes.push_back(std::move(extracted.back().meshes[0]));
    }
  }
  const SurfaceResult& first = extracted.front();
  report.secondsPolygonize = secondsSince(t);
  for (const SurfaceResult& e : extracted) {
    if (e.touchesBoundary) progress.log("warning: a level set still reaches the grid boundary; its mesh is open there");
  }
  progress.log("grid " + std::to_string(first.grid.cells.x()) + "x" + std::to_string(first.grid.cells.y()) + "x" +
               std::to_string(first.grid.cells.z()) + ", " + std::to_string(100.0 * first.stats.evaluatedFraction()) +
               "% of the nodes evaluated, " + std::to_string(report.secondsPolygonize) + " s");
  progress.end();
  report.grid = first.grid;
  report.gridStats = first.stats;
  report.boxGrowths = first.boxGrowths;
  report.touchesBoundary = first.touchesBoundary;

  // Every fit checks itself: zero-level components without input points and offset components away from
  // |delta| are listed; components below the minimum area fractions are dropped first.
  progress.start("self-check");
  report.selfCheck = cleanAndSelfCheck(meshes, isos, file.points.positions(), options.selfCheck);
  logSelfCheck(report.selfCheck, progress);
  progress.end();

  for (std::size_t i = 0; i < meshes.size(); ++i) {
    PipelineSurface s;
    s.field = options.separate ? i : 0;
    s.iso = options.separate ? 0.0 : isos[i];
    s.offset = isos[i];
    s.topology = analyzeTopology(meshes[i]);
    s.mesh = std::move(meshes[i]);
    result.surfaces.push_back(std::move(s));
  }
  report.secondsTotal = secondsSince(start);
  return result;
}

}  // namespace


bool PipelineReport::converged() const noexcept {
  const auto ok = [](const FitReport& r) {
    return std::all_of(r.levelReports.begin(), r.levelReports.end(),
                       [](const LevelReport& l) { return l.solve.iterations == 0 || l.solve.converged; });
  };
  if (!ok(fit)) return false;
  for (std::size_t j = 1; j < separateFits.size(); ++j) {
    if (!ok(separateFits[j])) return false;
  }
  return true;
}

PipelineResult runPipeline(const Device& device, const std::string& inputPath, const PipelineOptions& options,
                           Interrupter* interrupter) {
  const auto start = Clock::now();
  const Progress progress(interrupter);
  progress.start("read");
  PointReadOptions readOptions;
  readOptions.requireNormals = !options.estimateNormals;
  PointCloudFile file = readPointCloudWithReport(inputPath, readOptions);
  const double readSeconds = secondsSince(start);
  progress.end();
  return runOnPoints(device, std::move(file), inputPath, readSeconds, options, progress, start);
}

PipelineResult runPipeline(const Device& device, const PointSet& points, const PipelineOptions& options,
                           Interrupter* interrupter) {
  const auto start = Clock::now();
  PointCloudFile file{points, {}};
  file.report.points = points.size();
  file.report.normals = true;
  return runOnPoints(device, std::move(file), "", 0.0, options, Progress(interrupter), start);
}

std::vector<std::string> pipelineMeshNames(const PipelineResult& result, const std::string& meshFormat) {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < result.surfaces.size(); ++i) {
    names.push_back((i == 0 ? std::string("zero") : "offset" + std::to_string(i)) + "." + meshFormat);
  }
  return names;
}

std::vector<std::string> pipelineFieldNames(const PipelineResult& result) {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < result.fields.size(); ++i) {
    names.push_back(i == 0 ? std::string("field.dpxf") : "field_offset" + std::to_string(i) + ".dpxf");
  }
  return names;
}

void writePipelineOutputs(const PipelineResult& result, StagedFolder& folder, const std::string& meshFormat) {
  if (meshFormat != "ply" && meshFormat != "obj" && meshFormat != "stl") {
    throw InvalidArgument("mesh format must be ply, obj or stl, not '" + meshFormat + "'");
  }
  const auto t = Clock::now();
  const std::vector<std::string> meshNames = pipelineMeshNames(result, meshFormat);
  for (std::size_t i = 0; i < meshNames.size(); ++i) writeMesh(folder.path(meshNames[i]), result.surfaces[i].mesh);
  const std::vector<std::string> fieldNames = pipelineFieldNames(result);
  for (std::size_t i = 0; i < fieldNames.size(); ++i) result.fields[i].save(folder.path(fieldNames[i]));
  std::ostringstream json;
  writePipelineReport(json, result, meshFormat, secondsSince(t));
  {
    AtomicFile f(folder.path("report.json"));
    f.write(json.str());
    f.commit();
  }
  folder.commit();
}

void writePipelineOutputs(const PipelineResult& result, const std::string& outDir, const std::string& meshFormat) {
  StagedFolder folder(outDir);
  writePipelineOutputs(result, folder, meshFormat);
}

MeshPipelineResult runMeshPipeline(const Device& device, const ImplicitField& field, double iso,
                                   const SurfaceOptions& options, double minComponent, Interrupter* interrupter) {
  const Progress progress(interrupter);
  progress.start("polygonize");
  MeshPipelineResult r;
  r.extraction = extractSurfaces(device, field, {iso}, options, progress.polygonize());
  progress.end();
  r.mesh = dropSmallComponents(r.extraction.meshes[0], minComponent, &r.dropped);
  r.extraction.meshes.clear();
  if (r.dropped.components > 0) {
    std::ostringstream line;
    line << std::setprecision(4) << "dropped " << r.dropped.components << " component(s) below " << minComponent
         << " of the mesh's area (" << r.dropped.faces << " faces, " << 100.0 * r.dropped.areaFraction
         << "% of the area)";
    progress.log(line.str());
  }
  r.topology = analyzeTopology(r.mesh);
  return r;
}

}  // namespace duplexfit
