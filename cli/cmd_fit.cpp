// `duplexfit fit`: cloud in, one field out, plus meshes of the surface and every offset surface and a
// JSON report; `duplexfit mesh`: re-extract a level set from a saved field. Outputs are staged in a
// temporary folder inside the output folder and moved into place only when everything succeeded.
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>

#include <sys/resource.h>
#include <unistd.h>

#include "commands.hpp"
#include "staging.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/preprocess.hpp"
#include "duplexfit/self_check.hpp"
#include "duplexfit/surfaces.hpp"
#include "json.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kFitValued = {"offset", "output", "device", "precision", "validity-tol", "levels",
                                             "smoothing", "fit-tol", "tol", "max-iterations", "cell", "resolution",
                                             "format", "alpha", "anchor-skip", "normals-k", "denoise-sigma-s",
                                             "denoise-sigma-r", "denoise-radius", "denoise-iterations",
                                             "min-component", "min-offset-component"};
const std::vector<std::string> kMeshValued = {"iso", "output", "device", "precision", "cell", "resolution",
                                              "min-component", "min-offset-component"};

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

Device openDevice(Args& args, const std::function<void(const std::string&)>& log) {
  const std::string spec = args.str("device", "");
  const Device d = spec.empty() ? Device::openDefault() : Device::open(spec);
  log("device: " + d.description());
  return d;
}

void writeTopology(JsonWriter& w, const MeshTopology& t) {
  w.beginObject()
      .field("vertices", t.vertices)
      .field("faces", t.faces)
      .field("components", t.components)
      .field("watertight", t.watertight())
      .field("manifold", t.manifold())
      .field("oriented", t.oriented())
      .field("euler_characteristic", static_cast<long long>(t.eulerCharacteristic))
      .endObject();
}

void writeFitReport(JsonWriter& w, const FitReport& rep) {
  w.field("zero_normals", rep.zeroNormals).field("device", rep.device).field("precision", rep.precision);
  w.key("offsets").beginArray();
  for (double d : rep.offsets) w.value(d);
  w.endArray();
  w.field("off_surface_side", rep.offSurfaceSide).field("sigma0", rep.sigma0).field("sigma1", rep.sigma1);
  w.field("levels", rep.levels).field("stopped_early", rep.stoppedEarly);
  w.key("level_reports").beginArray();
  for (const LevelReport& l : rep.levelReports) {
    w.beginObject().field("level", l.level).field("sigma", l.sigma).field("surface_points", l.surfacePoints);
    w.key("offset_candidates").beginArray();
    for (auto v : l.offsetCandidates) w.value(v);
    w.endArray().key("offset_kept").beginArray();
    for (auto v : l.offsetKept) w.value(v);
    w.endArray();
    w.field("off_surface_candidates", l.offSurfaceCandidates).field("off_surface_kept", l.offSurfaceKept);
    w.key("offset_medial").beginArray();
    for (auto v : l.offsetMedial) w.value(v);
    w.endArray().field("off_surface_medial", l.offSurfaceMedial);
    w.key("anchors").beginObject().field("inside", l.anchorsInside).field("outside", l.anchorsOutside);
    w.field("skipped", l.anchorsSkipped).field("spacing", l.anchorSpacing).endObject();
    w.field("merged_centres", l.mergedCentres).field("centres", l.centres).field("nonzeros", l.nonZeros);
    w.field("max_residual_before", l.maxResidualBefore);
    w.key("cg").beginObject().field("converged", l.solve.converged).field("stop_reason", stopReasonName(l.solve.reason));
    w.field("iterations", l.solve.iterations).field("relative_residual", l.solve.relativeResidual);
    w.field("tolerance", l.solve.tolerance).endObject();
    w.key("seconds").beginObject().field("constraints", l.secondsConstraints).field("residual", l.secondsResidual);
    w.field("assembly", l.secondsAssembly).field("solve", l.secondsSolve).endObject();
    w.endObject();
  }
  w.endArray();
  w.field("E0", rep.e0).key("Edelta").beginArray();
  for (double e : rep.eDelta) w.value(e);
  w.endArray();
  const OffsetCorrectionReport& c = rep.correction;
  w.key("offset_correction").beginObject().field("applied", c.applied).field("sigma", c.sigma);
  w.field("points", c.points).field("nonzeros", c.nonZeros).field("mean_before", c.meanBefore);
  w.field("max_before", c.maxBefore).field("cg_iterations", c.solve.iterations);
  w.field("cg_converged", c.solve.converged).field("seconds", c.seconds).endObject();
  w.field("winding_seconds", rep.secondsWinding);
}

std::string meshExtension(Args& args) {
  const std::string f = args.str("format", "ply");
  if (f != "ply" && f != "obj" && f != "stl") throw UsageError("--format must be ply, obj or stl");
  return "." + f;
}

/// Default of --min-component (fit and mesh): connected components whose area is below this fraction of
/// their mesh's area are dropped before the meshes are written. 0 drops nothing.
constexpr double kDefaultMinComponent = 0.0;
/// Default of --min-offset-component (fit): the same for the offset meshes only. 0.1%: slivers of the δ
/// level where a part is almost exactly 2δ thick (eight_110k at δ = 0.05: 3 of 4 components, none in the
/// exact offset; fandisk_50k at 0.025: 7 of 8; docs/fidelity.md); the zero level keeps everything and the
/// self-check flags what carries no input point.
constexpr double kDefaultMinOffsetComponent = 0.001;

double fractionOption(Args& args, const char* name, double fallback) {
  const double f = args.num(name, fallback);
  if (!(f >= 0.0 && f < 1.0)) throw UsageError(std::string("--") + name + " must be an area fraction in [0, 1)");
  return f;
}

double minComponentOption(Args& args) { return fractionOption(args, "min-component", kDefaultMinComponent); }

std::string surfaceName(int surface) { return surface == 0 ? "zero level" : "offset " + std::to_string(surface); }

std::string formatBox(const Eigen::AlignedBox3d& box) {
  std::ostringstream s;
  s << std::setprecision(4) << "[" << box.min().x() << ", " << box.min().y() << ", " << box.min().z() << "] - ["
    << box.max().x() << ", " << box.max().y() << ", " << box.max().z() << "]";
  return s.str();
}

/// One warning line per component that failed the self-check, and per mesh that lost small components.
void logSelfCheck(const SelfCheckReport& r, const std::function<void(const std::string&)>& log) {
  for (const SurfaceSelfCheck& s : r.surfaces) {
    if (s.dropped.components == 0) continue;
    std::ostringstream line;
    const double fraction = s.surface == 0 ? r.minAreaFraction : std::max(r.minAreaFraction, r.minOffsetAreaFraction);
    line << std::setprecision(4) << surfaceName(s.surface) << ": dropped " << s.dropped.components
         << " component(s) below " << fraction << " of the mesh's area (" << s.dropped.faces << " faces, "
         << 100.0 * s.dropped.areaFraction << "% of the area)";
    log(line.str());
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
    log(line.str());
  }
  std::ostringstream line;
  line << "self-check: " << r.issues.size() << " component issue(s), " << r.seconds << " s";
  log(line.str());
}

void writeSelfCheck(JsonWriter& w, const SelfCheckReport& r, const std::vector<std::string>& meshNames) {
  w.key("self_check").beginObject().field("ok", r.ok()).field("points_checked", r.pointsChecked);
  w.field("point_tolerance", r.pointTolerance).field("min_component", r.minAreaFraction);
  w.field("min_offset_component", r.minOffsetAreaFraction);
  w.key("surfaces").beginArray();
  for (const SurfaceSelfCheck& s : r.surfaces) {
    w.beginObject().field("surface", s.surface).field("file", meshNames[static_cast<std::size_t>(s.surface)]);
    w.field("iso", s.iso).field("components", s.components).field("faces", s.faces).field("area", s.area);
    w.field("issues", s.issues);
    w.key("dropped").beginObject().field("components", s.dropped.components).field("faces", s.dropped.faces);
    w.field("area", s.dropped.area).field("area_fraction", s.dropped.areaFraction).endObject();
    w.endObject();
  }
  w.endArray().key("issues").beginArray();
  for (const ComponentIssue& i : r.issues) {
    w.beginObject().field("surface", i.surface).field("file", meshNames[static_cast<std::size_t>(i.surface)]);
    w.field("iso", i.iso).field("component", i.component).field("why", componentIssueName(i.why));
    w.field("faces", i.faces).field("vertices", i.vertices).field("area", i.area);
    w.field("area_fraction", i.areaFraction);
    w.key("box").beginObject().key("min").beginArray();
    for (int k = 0; k < 3; ++k) w.value(i.box.min()[k]);
    w.endArray().key("max").beginArray();
    for (int k = 0; k < 3; ++k) w.value(i.box.max()[k]);
    w.endArray().endObject();
    w.field("mean_distance", i.meanDistance).field("mean_deviation", i.meanDeviation);
    w.field("nearest_input_point", i.nearestInputPoint).endObject();
  }
  w.endArray().field("seconds", r.seconds).endObject();
}

}  // namespace

int cmdFit(Args& args) {
  const auto start = Clock::now();
  const bool quiet = args.flag("quiet");
  auto log = [quiet](const std::string& s) {
    if (!quiet) std::cerr << s << std::endl;
  };
  FitOptions options;
  options.offsets = parseNumberList(args.str("offset", ""), "offset");
  options.offsetsRelative = args.flag("offset-rel");
  options.normalsInward = args.flag("normals-inward");
  options.validityTolerance = args.num("validity-tol", options.validityTolerance);
  options.levels = static_cast<int>(args.integer("levels", 0));
  options.alpha = args.num("alpha", options.alpha);
  const bool denoise = args.flag("denoise");
  // A denoised cloud is fitted in approximation mode, s = 0.2 as the paper's Fig. 9, unless told otherwise.
  options.smoothing = args.num("smoothing", denoise ? 0.2 : 0.0);
  options.fitTolerance = args.num("fit-tol", 0.0);
  options.precision = parsePrecision(args.str("precision", "float").c_str());
  options.solver.relativeTolerance = args.num("tol", 0.0);
  options.solver.maxIterations = static_cast<int>(args.integer("max-iterations", options.solver.maxIterations));
  options.dropZeroNormalPoints = args.flag("drop-zero-normals");
  options.sideTest = args.flag("side-test");
  options.signAnchors = !args.flag("no-anchors");
  options.medialConstraints = !args.flag("no-medial");
  options.offsetCorrection = args.flag("offset-correction");
  options.anchorSkipFinest = static_cast<int>(args.integer("anchor-skip", options.anchorSkipFinest));
  SurfaceOptions surface;
  surface.cell = args.num("cell", 0.0);
  surface.resolution = static_cast<int>(args.integer("resolution", 0));
  surface.precision = options.precision;
  const std::string ext = meshExtension(args);
  const bool strict = args.flag("strict");
  const bool separate = args.flag("separate");
  SelfCheckOptions checkOptions;
  checkOptions.minAreaFraction = minComponentOption(args);
  checkOptions.minOffsetAreaFraction = fractionOption(args, "min-offset-component", kDefaultMinOffsetComponent);
  // Pre-processing (issue: noisy and unoriented scans): normals first (the filter needs them), then the
  // bilateral filter.
  const bool estimate = args.flag("estimate-normals");
  NormalOptions normalOptions;
  normalOptions.k = static_cast<int>(args.integer("normals-k", normalOptions.k));
  normalOptions.precision = options.precision;
  BilateralOptions filter;
  filter.sigmaSpatial = args.num("denoise-sigma-s", 0.0);
  filter.sigmaRange = args.num("denoise-sigma-r", 0.0);
  filter.radius = args.num("denoise-radius", 0.0);
  filter.iterations = static_cast<int>(args.integer("denoise-iterations", 1));
  filter.precision = options.precision;
  const fs::path outDir = args.str("output", ".");
  const Device device = openDevice(args, log);
  args.finish(1);
  if (args.positional().empty()) throw UsageError("fit needs an input cloud: duplexfit fit INPUT --offset D");
  const std::string input = args.positional()[0];

  Staging staging(outDir);  // fails early, before any work, if the folder is unusable

  auto t = Clock::now();
  PointReadOptions readOptions;
  readOptions.requireNormals = !estimate;
  PointCloudFile file = readPointCloudWithReport(input, readOptions);
  const double readSeconds = since(t);
  std::optional<NormalReport> normalReport;
  if (estimate) {
    NormalReport nr;
    log(std::string(file.report.normals ? "re-estimating" : "estimating") + " normals (k = " +
        std::to_string(normalOptions.k) + ") ...");
    try {
      file.points = estimateNormals(file.points.positions(), normalOptions, device, &nr);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(input + ": " + e.what());
    }
    log("normals: " + std::to_string(nr.components) + " component(s), " + std::to_string(nr.flippedComponents) +
        " flipped outward, " + std::to_string(nr.seconds) + " s");
    normalReport = nr;
  }
  const std::size_t merged = file.points.mergeDuplicates();
  std::optional<BilateralReport> filterReport;
  if (denoise) {
    BilateralReport br;
    log("bilateral filter ...");
    file.points = bilateralFilter(file.points, filter, device, &br);
    log("bilateral filter: sigma_s " + std::to_string(br.sigmaSpatial) + ", sigma_r " + std::to_string(br.sigmaRange) +
        ", mean displacement " + std::to_string(br.meanDisplacement) + ", " + std::to_string(br.seconds) + " s");
    filterReport = br;
  }
  checkFittable(file.points, input);  // errors name the file
  log("read " + std::to_string(file.report.points) + " points from " + input + " (" +
      std::to_string(merged) + " duplicates merged) in " + std::to_string(readSeconds) + " s");

  const FitProgressCallback progress = [&](const FitProgress& p) {
    if (quiet) return true;
    if (p.stage == "solve" && p.iteration > 0) {
      std::cerr << "  level " << p.level << "/" << p.levels << "  CG iteration " << p.iteration << "  residual "
                << p.residual << "\n";
    } else if (p.level > 0) {
      std::cerr << "level " << p.level << "/" << p.levels << ": " << p.stage
                << (p.message.empty() ? "" : " (" + p.message + ")") << "\n";
    } else {
      std::cerr << p.stage << (p.message.empty() ? "" : ": " + p.message) << "\n";
    }
    return true;
  };
  // Duplex mode: one field, every surface a level set of it. Separate mode: one field per surface, each
  // surface the 0-level of its own field (the baseline of the paper's Table 1).
  FitResult result;
  SeparateFitResult sep;
  if (separate) {
    sep = fitSeparate(device, file.points, options, progress);
    result.report = sep.zeroReport;
    result.report.offsets = sep.offsetDeltas;
    result.report.secondsTotal = sep.secondsTotal;
    for (const FitReport& r : sep.offsetReports) result.report.eDelta.push_back(r.e0);  // each at its own points
  } else {
    result = fit(device, file.points, options, progress);
  }
  FitReport& rep = result.report;
  rep.duplicatesMerged = merged;
  std::vector<const FitReport*> allReports{&rep};
  for (const FitReport& r : sep.offsetReports) allReports.push_back(&r);
  for (const FitReport* r : allReports) {
    for (const LevelReport& l : r->levelReports) {
      if (l.solve.iterations > 0 && !l.solve.converged) {
        log("warning: level " + std::to_string(l.level) + " CG did not converge (" + stopReasonName(l.solve.reason) +
            ", residual " + std::to_string(l.solve.relativeResidual) + ")");
      }
    }
  }

  t = Clock::now();
  std::vector<double> isos{0.0};
  isos.insert(isos.end(), rep.offsets.begin(), rep.offsets.end());
  log("polygonizing " + std::to_string(isos.size()) + " level sets ...");
  std::vector<SurfaceResult> extracted;
  std::vector<Mesh> meshes;
  if (!separate) {
    extracted.push_back(extractSurfaces(device, result.field, isos, surface));
    meshes = std::move(extracted.back().meshes);
  } else {
    // The separate fields share the zero field's grid cell unless the user chose one, so that both modes
    // mesh at the same resolution.
    SurfaceOptions same = surface;
    if (same.cell <= 0.0 && same.resolution <= 0) {
      same.cell = surfaceGrid(sep.zero, isos, surface).cellSize().maxCoeff();
    }
    extracted.push_back(extractSurfaces(device, sep.zero, {0.0}, same));
    meshes.push_back(std::move(extracted.back().meshes[0]));
    for (const ImplicitField& f : sep.offsets) {
      extracted.push_back(extractSurfaces(device, f, {0.0}, same));
      meshes.push_back(std::move(extracted.back().meshes[0]));
    }
  }
  const SurfaceResult& surfaces = extracted.front();
  const double meshSeconds = since(t);
  for (const SurfaceResult& e : extracted) {
    if (e.touchesBoundary) log("warning: a level set still reaches the grid boundary; its mesh is open there");
  }
  log("grid " + std::to_string(surfaces.grid.cells.x()) + "x" + std::to_string(surfaces.grid.cells.y()) + "x" +
      std::to_string(surfaces.grid.cells.z()) + ", " + std::to_string(100.0 * surfaces.stats.evaluatedFraction()) +
      "% of the nodes evaluated, " + std::to_string(meshSeconds) + " s");

  // Every fit checks itself: zero-level components without input points and offset components away from
  // |delta| are listed (and fail --strict); components below --min-component are dropped first.
  const SelfCheckReport selfCheckReport = cleanAndSelfCheck(meshes, isos, file.points.positions(), checkOptions);
  logSelfCheck(selfCheckReport, log);

  t = Clock::now();
  std::vector<std::string> meshNames;
  std::vector<MeshTopology> topo;
  for (std::size_t i = 0; i < meshes.size(); ++i) {
    const std::string name = i == 0 ? "zero" + ext : "offset" + std::to_string(i) + ext;
    writeMesh(staging.path(name), meshes[i]);
    meshNames.push_back(name);
    topo.push_back(analyzeTopology(meshes[i]));
  }
  std::vector<std::string> fieldNames;
  if (!separate) {
    result.field.save(staging.path("field.dpxf"));
    fieldNames.push_back("field.dpxf");
  } else {
    sep.zero.save(staging.path("field.dpxf"));
    fieldNames.push_back("field.dpxf");
    for (std::size_t j = 0; j < sep.offsets.size(); ++j) {
      fieldNames.push_back("field_offset" + std::to_string(j + 1) + ".dpxf");
      sep.offsets[j].save(staging.path(fieldNames.back()));
    }
  }

  std::ostringstream json;
  JsonWriter w(json);
  w.beginObject().field("input", input).field("points", file.report.points).field("duplicates_merged", merged);
  w.field("mode", separate ? "separate" : "duplex").field("side_test", options.sideTest);
  w.key("preprocessing").beginObject();
  w.key("normals");
  if (normalReport) {
    const NormalReport& n = *normalReport;
    w.beginObject().field("method", "PCA + Riemannian MST propagation + enclosed-volume sign");
    w.field("k", n.k).field("graph_k", n.graphK).field("input_had_normals", file.report.normals);
    w.field("components", n.components).field("flipped_components", n.flippedComponents);
    w.field("ambiguous_components", n.ambiguousComponents).field("nested_components", n.nestedComponents);
    w.field("degenerate", n.degenerate).field("non_planar", n.nonPlanar).field("seconds", n.seconds).endObject();
  } else {
    w.null();
  }
  w.key("denoise");
  if (filterReport) {
    const BilateralReport& b = *filterReport;
    w.beginObject().field("method", "bilateral point filter (docs/method.md section 9)");
    w.field("sigma_spatial", b.sigmaSpatial).field("sigma_range", b.sigmaRange).field("radius", b.radius);
    w.field("area_sigma", b.areaSigma).field("iterations", b.iterations).field("symmetric_range", b.symmetricRange);
    w.field("mean_neighbors", b.meanNeighbors).field("moved", b.moved);
    w.field("max_displacement", b.maxDisplacement).field("mean_displacement", b.meanDisplacement);
    w.field("seconds", b.seconds).endObject();
  } else {
    w.null();
  }
  w.endObject();
  if (!separate) {
    writeFitReport(w, rep);
  } else {
    w.field("device", rep.device).field("precision", rep.precision).key("offsets").beginArray();
    for (double d : sep.offsetDeltas) w.value(d);
    w.endArray();
    w.field("E0", rep.e0).key("Edelta").beginArray();
    for (const FitReport& r : sep.offsetReports) w.value(r.e0);
    w.endArray();
    w.key("fits").beginArray();
    for (std::size_t i = 0; i <= sep.offsetReports.size(); ++i) {
      w.beginObject().field("surface", i == 0 ? std::string("zero") : "offset" + std::to_string(i));
      w.field("delta", i == 0 ? 0.0 : sep.offsetDeltas[i - 1]);
      w.field("fitted_points", i == 0 ? file.points.size() : sep.offsetPoints[i - 1]);
      writeFitReport(w, i == 0 ? sep.zeroReport : sep.offsetReports[i - 1]);
      w.endObject();
    }
    w.endArray();
  }
  w.key("meshes").beginArray();
  for (std::size_t i = 0; i < meshNames.size(); ++i) {
    w.beginObject().field("file", meshNames[i]).field("iso", separate ? 0.0 : isos[i]);
    w.field("field", separate ? fieldNames[i] : fieldNames[0]).key("topology");
    writeTopology(w, topo[i]);
    w.endObject();
  }
  w.endArray();
  writeSelfCheck(w, selfCheckReport, meshNames);
  w.key("grid").beginObject().field("nx", surfaces.grid.cells.x()).field("ny", surfaces.grid.cells.y());
  w.field("nz", surfaces.grid.cells.z()).field("cell", surfaces.grid.cellSize().maxCoeff());
  w.field("evaluated_fraction", surfaces.stats.evaluatedFraction()).field("box_growths", surfaces.boxGrowths);
  w.field("continued_cells", surfaces.stats.continuedCells).field("touches_boundary", surfaces.touchesBoundary);
  w.field("sampler_seconds", surfaces.stats.samplerSeconds).field("extraction_seconds", surfaces.stats.extractionSeconds);
  w.endObject();
  w.key("seconds").beginObject().field("read", readSeconds).field("hierarchy", rep.secondsHierarchy);
  w.field("fit", rep.secondsTotal).field("polygonize", meshSeconds).field("write", since(t));
  w.field("total", since(start)).endObject();
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  w.field("peak_rss_mib", static_cast<double>(usage.ru_maxrss) / 1024.0);
  w.endObject();
  {
    AtomicFile f(staging.path("report.json"));
    f.write(json.str());
    f.commit();
  }
  staging.commit();

  std::cout << std::setprecision(4) << "fit " << (separate ? "(separate) " : "") << input << ": " << file.report.points << " points, " << rep.levels
            << " levels, E0 " << rep.e0;
  for (std::size_t j = 0; j < rep.eDelta.size(); ++j) std::cout << ", E(" << rep.offsets[j] << ") " << rep.eDelta[j];
  std::cout << ", " << since(start) << " s\n";
  for (std::size_t i = 0; i < meshNames.size(); ++i) {
    std::cout << "  " << (outDir / meshNames[i]).string() << (separate && i > 0 ? "  offset " : "  iso ") << isos[i]
              << ": " << topo[i].faces
              << " triangles, " << topo[i].components << " component(s), "
              << (topo[i].watertight() && topo[i].manifold() ? "watertight 2-manifold" : "NOT watertight/manifold")
              << "\n";
  }
  if (!selfCheckReport.ok()) {
    std::cout << "  self-check: " << selfCheckReport.issues.size() << " component issue(s), listed in report.json\n";
  }
  std::cout << " ";
  for (const std::string& f : fieldNames) std::cout << " " << (outDir / f).string() << ",";
  std::cout << " " << (outDir / "report.json").string() << "\n";
  bool converged = true;
  for (const FitReport* r : allReports) {
    for (const LevelReport& l : r->levelReports) converged = converged && (l.solve.iterations == 0 || l.solve.converged);
  }
  return strict && (!converged || !selfCheckReport.ok()) ? kNumerical : 0;
}

int cmdMesh(Args& args) {
  const bool quiet = args.flag("quiet");
  auto log = [quiet](const std::string& s) {
    if (!quiet) std::cerr << s << std::endl;
  };
  const double iso = args.num("iso", 0.0);
  SurfaceOptions surface;
  surface.cell = args.num("cell", 0.0);
  surface.resolution = static_cast<int>(args.integer("resolution", 0));
  surface.precision = parsePrecision(args.str("precision", "float").c_str());
  const double minComponent = minComponentOption(args);
  const std::string out = args.str("output", "mesh.ply");
  const Device device = openDevice(args, log);
  args.finish(1);
  if (args.positional().empty()) throw UsageError("mesh needs a field file: duplexfit mesh FIELD --iso V -o OUT");
  const ImplicitField field = ImplicitField::load(args.positional()[0]);
  SurfaceResult s = extractSurfaces(device, field, {iso}, surface);
  DroppedComponents dropped;
  s.meshes[0] = dropSmallComponents(s.meshes[0], minComponent, &dropped);
  if (dropped.components > 0) {
    std::ostringstream line;
    line << std::setprecision(4) << "dropped " << dropped.components << " component(s) below " << minComponent
         << " of the mesh's area (" << dropped.faces << " faces, " << 100.0 * dropped.areaFraction << "% of the area)";
    log(line.str());
  }
  writeMesh(out, s.meshes[0]);
  const MeshTopology t = analyzeTopology(s.meshes[0]);
  std::cout << out << ": iso " << iso << ", " << t.faces << " triangles, " << t.components << " component(s), "
            << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold") << "\n";
  return 0;
}

}  // namespace duplexfit::cli
