// runPipeline: the job of `duplexfit fit` (read, pre-process, fit, extract, self-check), and
// runMeshPipeline (`duplexfit mesh`). Every operation gets the caller's Interrupter as it is.
#include "duplexfit/pipeline.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <exception>
#include <functional>
#include <future>
#include <iomanip>
#include <iterator>
#include <memory>
#include <optional>
#include <sstream>
#include <system_error>
#include <thread>
#include <utility>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/timer.hpp"
#include "parallel/workers.hpp"
#include "surfaces/splice.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

/// The Interrupter (or none) of a pipeline run, with the stage bookkeeping.
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
  Interrupter* interrupter() const { return i_; }

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

std::string numText(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

/// The shell's options checked before any work: an inward offset, holes only in duplex mode.
void validateShell(const PipelineOptions& options) {
  const ShellOptions& s = options.shellOptions;
  if (!options.shell) {
    if (s.drained()) throw InvalidArgument("--drain-hole needs --shell (holes are cut in the printable shell)");
    return;
  }
  const std::vector<double>& offsets = options.fit.offsets;
  if (std::none_of(offsets.begin(), offsets.end(), [](double d) { return d > 0.0; })) {
    std::string given;
    for (double d : offsets) given += (given.empty() ? "" : ",") + numText(d);
    throw InvalidArgument("--shell needs an inward offset: --offset D with D > 0 (positive = inward)" +
                          (given.empty() ? std::string(", none given") : "; given: " + given));
  }
  if (s.drained() && options.separate) {
    throw InvalidArgument("--drain-hole needs the duplex field (one field for both surfaces), not --separate");
  }
  for (const DrainHole& h : s.drainHoles) {
    if (!h.point.allFinite() || !(h.radius > 0.0) || !std::isfinite(h.radius)) {
      throw InvalidArgument("--drain-hole: the point must be finite and the radius > 0 (got radius " +
                            numText(h.radius) + ")");
    }
  }
  if (s.autoDrainHoles && !(s.autoDrainRadius >= 0.0 && std::isfinite(s.autoDrainRadius))) {
    throw InvalidArgument("--drain-hole auto: the radius must be > 0");
  }
}

/// One line about a shell: its mesh, volumes and intersections.
std::string shellSummary(const ShellReport& r) {
  const MeshTopology& t = r.topology;
  std::ostringstream line;
  line << std::setprecision(5) << "shell (iso 0 and " << r.offset << "): " << t.faces << " triangles, " << t.components
       << " component(s), " << (t.watertight() && t.manifold() && t.oriented() ? "watertight oriented 2-manifold"
                                                                             : "NOT watertight/manifold/oriented")
       << ", volume " << r.volume << " (zero - offset " << r.zeroMinusOffsetVolume() << ", relative difference "
       << r.relativeDifference() << "), ";
  if (!r.intersectionsChecked) {
    line << "intersections not checked";
  } else {
    line << (r.intersects() ? std::to_string(r.intersections) + " intersecting triangle pair(s)" : "no intersection")
         << (r.intersectionsComplete ? "" : " (check stopped at its work bound)");
  }
  if (!r.drainHoles.empty()) line << ", " << r.drainHoles.size() << " drain hole(s)";
  if (r.droppedCavities > 0) line << ", " << r.droppedCavities << " small cavity(ies) filled";
  return line.str();
}

/// A warning per hole narrower than two grid cells (its mesh is then coarse).
void warnCoarseHoles(const ShellReport& r, const GridSpec& grid, const Progress& progress) {
  const double cell = grid.cellSize().maxCoeff();
  for (const DrainHole& h : r.drainHoles) {
    if (h.radius < 2.0 * cell) {
      progress.log("warning: drain hole radius " + numText(h.radius) + " is under two grid cells (" + numText(cell) +
                   "): its mesh is coarse; use a smaller --cell");
    }
  }
}

/// One progress line per finished mesh: what the cleaning and simplification did, and the deviation.
void logFinish(const std::string& name, const MeshFinishReport& r, const Progress& progress) {
  std::ostringstream line;
  line << std::setprecision(4) << name << ": ";
  if (r.clean.facesBefore > 0) {
    line << r.clean.collapses << " edges collapsed, " << r.clean.flips << " flipped, " << r.clean.facesBefore
         << " -> " << r.clean.facesAfter << " triangles, " << r.clean.float32DegenerateBefore << " -> "
         << r.clean.float32DegenerateAfter << " float32-degenerate; ";
  }
  if (r.simplify.applied) {
    line << "simplified " << r.simplify.facesBefore << " -> " << r.simplify.facesAfter << " triangles"
         << (r.simplify.fallback ? " (meshoptimizer changed the topology: by the library's own collapses)" : "")
         << (r.simplify.topologyKept ? "" : " (not: the topology changed)") << "; ";
  }
  if (r.project.applied) {
    line << r.project.moved << " vertices moved onto the level set, " << r.project.splits << " edges split; ";
  }
  if (r.deviationMeasured) {
    line << "deviation from the level set " << r.deviation.max << " (" << 100.0 * r.deviation.relativeMax
         << "% of the largest side)";
  }
  progress.log(line.str());
}

/// finishSurfaces on the pipeline's meshes in place: one call with the fit's evaluator in duplex mode (or
/// one built here), one per field in separate mode.
std::vector<MeshFinishReport> finishMeshes(const Device& device, const std::vector<ImplicitField>& fields,
                                           const FieldEvaluator* evaluator, std::vector<Mesh>& meshes,
                                           const std::vector<double>& isos, bool separate, double cell,
                                           const MeshFinishOptions& options, Precision precision,
                                           const Progress& progress) {
  progress.start("finish");
  std::vector<MeshFinishReport> reports;
  if (!separate) {
    std::unique_ptr<FieldEvaluator> own;
    if (!evaluator) {
      own = std::make_unique<FieldEvaluator>(device, fields[0], precision);
      evaluator = own.get();
    }
    FinishResult r = finishSurfaces(*evaluator, fields[0], std::move(meshes), isos, cell, options,
                                    progress.interrupter());
    meshes = std::move(r.meshes);
    reports = std::move(r.reports);
  } else {
    for (std::size_t i = 0; i < meshes.size(); ++i) {
      const FieldEvaluator e(device, fields[i], precision);
      std::vector<Mesh> one;
      one.push_back(std::move(meshes[i]));
      FinishResult r = finishSurfaces(e, fields[i], std::move(one), {0.0}, cell, options, progress.interrupter());
      meshes[i] = std::move(r.meshes[0]);
      reports.push_back(r.reports[0]);
    }
  }
  for (std::size_t i = 0; i < reports.size(); ++i) logFinish(surfaceName(static_cast<int>(i)), reports[i], progress);
  progress.end();
  return reports;
}

/// Extractions of one level set by the neck pass, at most.
constexpr int kNeckRounds = 2;
/// The neck's cells: those within kNeckRadius of each point beyond the limit (a cube of 2r + 1 cells a
/// side), which bound the zone replaced and the neckPassMaxCells test; of them, the cells within
/// kDeepRadius of the points are refined one level more. (Both were 2: the level set lies within the
/// deviation, under a cell, of the points, and the deeper cells were most of the extraction's tetrahedra;
/// docs/method.md §7 "Deeper cells near the points only".)
constexpr int kNeckRadius = 2;
constexpr int kDeepRadius = 1;

/// The local replacement's zones around the neck pass's cells: the finished mesh's faces within
/// kSpliceInner + kSpliceGap cells go (the outer zone), and the new extraction's there come, those about a
/// cell from the faces that stay, in pieces that reach within kSpliceInner cells (spliceZone); the band
/// between fills the rest.
constexpr int kSpliceInner = 4;
constexpr int kSpliceGap = 1;
/// A later round whose local replacement is refused extracts the whole level set again only where the
/// earlier rounds left the mesh farther than this many times the deviation limit (docs/method.md §7: the
/// bunny twin's offset came out of its local first round 1.02 times the limit, and the whole level set
/// again took 2.2 s of a 9.4 s fit for 0.1017% -> 0.0931% of the side).
constexpr double kWholeAgainFactor = 2.0;
/// Cells around each cluster of the replaced zone in the box extracted again.
constexpr int kBoxMargin = 1;
/// Boxes (separate clusters of the zone) at most; more leave the round to the whole-mesh pass.
constexpr std::size_t kMaxBoxes = 64;

/// The level set {f = iso} extracted again in boxes of the grid's lattice around the clusters of `outer`
/// (sorted linear cell ids; a box per cluster, kBoxMargin cells around it, overlapping boxes merged), with
/// `deeper` (cells of `grid`) refined one level more; the boxes' meshes as one. The patch a splice takes
/// from it lies in the inner zone, well inside each box, so the boxes' own borders do not matter.
Mesh extractAround(const FieldEvaluator& evaluator, const GridSpec& grid, const std::vector<std::int64_t>& outer,
                   double iso, const PolygonizeOptions& po, const std::vector<std::array<int, 3>>& deeper,
                   const Progress& progress) {
  const std::vector<std::array<int, 6>> boxes = detail::zoneBoxes(grid, outer, kBoxMargin);
  if (boxes.size() > kMaxBoxes) {
    throw InvalidArgument(std::to_string(boxes.size()) + " separate zones (more than " + std::to_string(kMaxBoxes) + ")");
  }
  const Eigen::Vector3d h = grid.cellSize();
  Mesh all;
  std::vector<Mesh> parts;
  for (const auto& b : boxes) {
    GridSpec sub;
    Eigen::Vector3d lo, hi;
    for (int a = 0; a < 3; ++a) {
      lo(a) = grid.box.min()(a) + h(a) * b[static_cast<std::size_t>(a)];
      hi(a) = grid.box.min()(a) + h(a) * (b[static_cast<std::size_t>(3 + a)] + 1);
      sub.cells(a) = b[static_cast<std::size_t>(3 + a)] - b[static_cast<std::size_t>(a)] + 1;
    }
    sub.box = Eigen::AlignedBox3d(lo, hi);
    PolygonizeOptions local = po;
    local.refineDeeperCells.clear();
    for (const auto& c : deeper) {
      bool inside = true;
      for (int a = 0; a < 3; ++a) {
        inside = inside && c[static_cast<std::size_t>(a)] >= b[static_cast<std::size_t>(a)] &&
                 c[static_cast<std::size_t>(a)] <= b[static_cast<std::size_t>(3 + a)];
      }
      if (inside) local.refineDeeperCells.push_back({c[0] - b[0], c[1] - b[1], c[2] - b[2]});
    }
    parts.push_back(std::move(polygonize(valueSampler(evaluator), sub, {iso}, local, progress.interrupter()).meshes[0]));
  }
  Eigen::Index nv = 0, nf = 0;
  for (const Mesh& m : parts) {
    nv += m.vertices.rows();
    nf += m.faces.rows();
  }
  all.vertices.resize(nv, 3);
  all.faces.resize(nf, 3);
  nv = nf = 0;
  for (const Mesh& m : parts) {
    all.vertices.middleRows(nv, m.vertices.rows()) = m.vertices;
    all.faces.middleRows(nf, m.faces.rows()) = m.faces.array() + static_cast<std::int32_t>(nv);
    nv += m.vertices.rows();
    nf += m.faces.rows();
  }
  return all;
}

/// spliceZone of `extracted` into `mesh` with the finishing's options, and what every local replacement
/// must pass: a bubble of the patch dropped (as the whole extraction drops them), a closed oriented
/// 2-manifold stays one (`before`: mesh's topology), no triangle of the patch degenerate in float32 and no
/// intersecting pair. False with `why` otherwise.
bool spliceChecked(const FieldEvaluator& evaluator, const ImplicitField& field, const GridSpec& grid, double iso,
                   const SurfaceOptions& surface, double minComponent, const Mesh& mesh, const Mesh& extracted,
                   const std::vector<std::int64_t>& inner, const std::vector<std::int64_t>& outer,
                   const MeshTopology& before, detail::SpliceResult& sp, std::string& why) {
  const double side = field.bounds().sizes().maxCoeff(), cell = grid.cellSize().maxCoeff();
  sp = detail::spliceZone(mesh, extracted, grid, inner, outer, detail::fieldGradientSampler(evaluator), iso, side,
                          detail::finishCleanOptions(surface.finish, cell),
                          detail::finishProjectOptions(surface.finish, side, cell));
  if (!sp.ok) {
    why = sp.why;
    return false;
  }
  MeshTopology after = analyzeTopology(sp.mesh);
  if (after.components > before.components) {  // a bubble of the patch, as the whole extraction drops them
    DropResult dropped = dropSmallComponents(sp.mesh, minComponent);
    if (dropped.dropped.components > 0) {
      sp.mesh = std::move(dropped.mesh);
      sp.newFaces.clear();  // renumbered: test every face below
      after = analyzeTopology(sp.mesh);
    }
  }
  if (!(after.watertight() && after.manifold() && after.oriented()) &&
      (before.watertight() && before.manifold() && before.oriented())) {
    why = "the spliced mesh is not a closed oriented 2-manifold";
    return false;
  }
  // The band's triangles join the hole's loops, whose vertices the patch's cleaning may not move: one of
  // them can be degenerate once written in float32 (joint_40k's zero level at δ = −0.02: four, and `check`
  // refused the mesh that `fit` called sound).
  {
    std::size_t degenerate = 0;
    const auto test = [&](Eigen::Index f) {
      const Eigen::Vector3d a = sp.mesh.vertices.row(sp.mesh.faces(f, 0)).transpose();
      const Eigen::Vector3d b = sp.mesh.vertices.row(sp.mesh.faces(f, 1)).transpose();
      const Eigen::Vector3d c = sp.mesh.vertices.row(sp.mesh.faces(f, 2)).transpose();
      if (float32Degenerate(a, b, c)) ++degenerate;
    };
    if (sp.newFaces.empty()) {
      for (Eigen::Index f = 0; f < sp.mesh.faces.rows(); ++f) test(f);
    } else {
      for (const std::int64_t f : sp.newFaces) test(static_cast<Eigen::Index>(f));
    }
    if (degenerate > 0) {
      why = std::to_string(degenerate) + " triangles of the patch degenerate in float32";
      return false;
    }
  }
  CheckOptions co;
  co.listedPairs = 0;
  const SelfIntersections crossing = findSelfIntersections(sp.mesh, co, sp.newFaces.empty() ? nullptr : &sp.newFaces);
  if (crossing.count > 0) {
    why = std::to_string(crossing.count) + " intersecting triangle pairs in the patch";
    return false;
  }
  return true;
}

/// The neck pass's local replacement on `mesh` (see neckPass): the faces around `zoneCells` are replaced by
/// the level set extracted with `cells` refined one level more. True when kept (mesh, finish's deviation and
/// r's counts updated); false with `why` otherwise, nothing changed. `before`: mesh's topology. In the last
/// round the result must be within the deviation limit (the whole extraction is the caller's last resort).
bool localNeckPassOnce(const FieldEvaluator& evaluator, const ImplicitField& field, const GridSpec& grid, double iso,
                       const SurfaceOptions& surface, double minComponent, const std::vector<std::array<int, 3>>& cells,
                       const std::vector<std::array<int, 3>>& zoneCells, const MeshTopology& before, bool lastRound,
                       PolygonizeOptions po, Mesh& mesh, MeshFinishReport& finish, NeckPassReport& r, std::string& why,
                       const std::string& label, const Progress& progress) {
  const std::vector<std::int64_t> inner = detail::dilatedCells(grid, zoneCells, kSpliceInner);
  const std::vector<std::int64_t> outer = detail::dilatedCells(grid, zoneCells, kSpliceInner + kSpliceGap);
  const Mesh extracted = extractAround(evaluator, grid, outer, iso, po, cells, progress);
  detail::SpliceResult sp;
  if (!spliceChecked(evaluator, field, grid, iso, surface, minComponent, mesh, extracted, inner, outer, before, sp, why)) {
    return false;
  }
  // Judged where it changed, on every vertex and face centre: the faces put in against those taken out
  // (the whole mesh's measure samples a stride, whose maximum moves with the mesh).
  const LevelSetDeviation out = levelSetDeviation(evaluator, field, sp.removed, iso, 0);
  const LevelSetDeviation in = levelSetDeviation(evaluator, field, sp.patch, iso, 0);
  if (!(in.relativeMax < out.relativeMax)) {
    std::ostringstream line;
    line << std::setprecision(4) << "no closer where it changed: " << 100.0 * out.relativeMax << "% -> "
         << 100.0 * in.relativeMax << "%";
    why = line.str();
    return false;
  }
  const LevelSetDeviation d = levelSetDeviation(evaluator, field, sp.mesh, iso, surface.finish.deviationSamples);
  const double was = finish.deviation.relativeMax;
  if (lastRound && !(d.max <= d.limit)) {
    std::ostringstream line;
    line << std::setprecision(4) << "in the last round still beyond the limit: " << 100.0 * d.relativeMax << "%";
    why = line.str();
    return false;
  }
  std::ostringstream line;
  line << std::setprecision(4) << label << ", local: " << cells.size() << " cells refined one level more, "
       << sp.removedFaces << " faces replaced by " << sp.newFaces.size() << " (" << sp.bandFaces << " in the band, "
       << sp.loops << " loops): deviation there " << 100.0 * out.relativeMax << "% -> " << 100.0 * in.relativeMax
       << "%, of the mesh " << 100.0 * was << "% -> " << 100.0 * d.relativeMax << "% of the largest side, kept";
  progress.log(line.str());
  r.removedFaces += sp.removedFaces;
  r.patchFaces += static_cast<std::size_t>(sp.mesh.faces.rows()) + sp.removedFaces -
                  static_cast<std::size_t>(mesh.faces.rows());
  mesh = std::move(sp.mesh);
  finish.deviation = d;
  finish.deviationMeasured = true;
  return true;
}

/// localNeckPassOnce, with an extraction or splice that fails (a box the polygoniser refuses, too many
/// zones, memory) left to the whole-mesh pass of the caller; a cancellation is not.
bool localNeckPass(const FieldEvaluator& evaluator, const ImplicitField& field, const GridSpec& grid, double iso,
                   const SurfaceOptions& surface, double minComponent, const std::vector<std::array<int, 3>>& cells,
                   const std::vector<std::array<int, 3>>& zoneCells, const MeshTopology& before, bool lastRound,
                   const PolygonizeOptions& po, Mesh& mesh, MeshFinishReport& finish, NeckPassReport& r,
                   std::string& why, const std::string& label, const Progress& progress) {
  try {
    return localNeckPassOnce(evaluator, field, grid, iso, surface, minComponent, cells, zoneCells, before, lastRound,
                             po, mesh, finish, r, why, label, progress);
  } catch (const Cancelled&) {
    throw;
  } catch (const std::exception& e) {
    why = e.what();
    return false;
  }
}

/// The level set {f = iso} extracted again on the whole grid with `po`, its components below minComponent
/// dropped, and finished: the neck pass's whole-mesh round and the phantom repair's last resort.
FinishResult extractWhole(const FieldEvaluator& evaluator, const ImplicitField& field, const GridSpec& grid, double iso,
                          const SurfaceOptions& surface, double minComponent, const PolygonizeOptions& po,
                          const Progress& progress) {
  PolygonizeResult extracted = polygonize(valueSampler(evaluator), grid, {iso}, po, progress.interrupter());
  std::vector<Mesh> one;
  one.push_back(dropSmallComponents(extracted.meshes[0], minComponent).mesh);
  extracted.meshes.clear();
  return finishSurfaces(evaluator, field, std::move(one), {iso}, grid.cellSize().maxCoeff(), surface.finish,
                        progress.interrupter());
}

/// A mesh the phantom repair handed back (PhantomRepairResult::reextract): its level set of the repaired
/// field extracted again in the cells around `seeds` (its vertices near the correction, input units) and
/// spliced in, as the neck pass's local replacement is. True with `mesh` and `finish`'s deviation updated
/// and a line for the log in `lines`; false with `why` otherwise (nothing changed). The patch must come
/// within the deviation limit, or within the mesh's own deviation before, where it changed.
bool spliceAroundRepair(const FieldEvaluator& evaluator, const ImplicitField& field, const GridSpec& grid, double iso,
                        const SurfaceOptions& surface, double minComponent, const std::vector<Eigen::Vector3d>& seeds,
                        Mesh& mesh, MeshFinishReport& finish, std::string& why, const std::string& name,
                        std::vector<std::string>& lines, const Progress& progress) {
  if (!(surface.finish.clean && surface.finish.project)) {
    why = "the meshes are not cleaned and projected";
    return false;
  }
  try {
    std::vector<std::array<int, 3>> zone;
    zone.reserve(seeds.size());
    for (const Eigen::Vector3d& p : seeds) zone.push_back(detail::cellOf(grid, p));
    std::sort(zone.begin(), zone.end());
    zone.erase(std::unique(zone.begin(), zone.end()), zone.end());
    const std::vector<std::int64_t> inner = detail::dilatedCells(grid, zone, kSpliceInner);
    const std::vector<std::int64_t> outer = detail::dilatedCells(grid, zone, kSpliceInner + kSpliceGap);
    const Mesh extracted = extractAround(evaluator, grid, outer, iso, surfacePolygonizeOptions(field, surface), {}, progress);
    detail::SpliceResult sp;
    if (!spliceChecked(evaluator, field, grid, iso, surface, minComponent, mesh, extracted, inner, outer,
                       analyzeTopology(mesh), sp, why)) {
      return false;
    }
    const LevelSetDeviation in = levelSetDeviation(evaluator, field, sp.patch, iso, 0);
    if (!(in.max <= std::max(in.limit, finish.deviation.max))) {
      std::ostringstream line;
      line << std::setprecision(4) << "the patch is " << 100.0 * in.relativeMax << "% of the largest side off its level set";
      why = line.str();
      return false;
    }
    const LevelSetDeviation d = levelSetDeviation(evaluator, field, sp.mesh, iso, surface.finish.deviationSamples);
    std::ostringstream line;
    line << std::setprecision(4) << "phantom repair: " << name << " extracted again around the correction, "
         << sp.removedFaces << " faces replaced by " << sp.patch.faces.rows() << " (" << sp.bandFaces << " in the band, "
         << sp.loops << " loops): deviation there " << 100.0 * in.relativeMax << "%, of the mesh "
         << 100.0 * d.relativeMax << "% of the largest side";
    lines.push_back(line.str());
    mesh = std::move(sp.mesh);
    finish.deviation = d;
    finish.deviationMeasured = true;
    return true;
  } catch (const Cancelled&) {
    throw;
  } catch (const std::exception& e) {
    why = e.what();
    return false;
  }
}

/// SurfaceOptions::neckPassMaxFaces for one finished mesh of {f = iso} extracted on `grid`: returns true when
/// the mesh and its report were replaced.
/// Whether neckPass has anything to do on `mesh` (points beyond the limit, within its bounds).
bool wantsNeckPass(const SurfaceOptions& surface, const Mesh& mesh, const MeshFinishReport& finish) {
  const int levels = surface.polygonize.refineLevels;
  return finish.deviationMeasured && !finish.deviation.aboveLimitAt.empty() && surface.neckPassMaxFaces > 0 &&
         static_cast<std::size_t>(mesh.faces.rows()) <= surface.neckPassMaxFaces && levels >= 1 && levels <= 2;
}

bool neckPass(const FieldEvaluator& evaluator, const ImplicitField& field, const GridSpec& grid, double iso,
              const SurfaceOptions& surface, double minComponent, Mesh& mesh, MeshFinishReport& finish,
              const std::string& name, const Progress& progress) {
  if (!wantsNeckPass(surface, mesh, finish)) return false;
  const auto start = Clock::now();
  NeckPassReport r;
  r.applied = true;
  r.facesBefore = static_cast<std::size_t>(mesh.faces.rows());
  r.maxBefore = finish.deviation.relativeMax;
  // Up to two rounds: the second adds the cells of the points the first left beyond the limit (a neck
  // longer than the first round's cells).
  std::vector<std::array<int, 3>> cells, replaced;  // this round's cells; those the mesh has refined already
  std::vector<std::array<int, 3>> deep;             // of them, the cells refined one level more
  bool kept = false;
  // The mesh's topology before any round, taken once a round will run (a pass refused for its cells, as on
  // the wheels' meshes, needs none: 0.1 s a million faces).
  std::optional<MeshTopology> first;
  for (int round = 0; round < kNeckRounds; ++round) {
    const LevelSetDeviation& d = finish.deviation;
    if (!finish.deviationMeasured || d.aboveLimitAt.empty()) break;
    // The cells of the points beyond half the limit (the neck's extent, so that one round usually covers
    // it) or, when those span too many cells, of the points beyond the limit, with the cells within
    // kNeckRadius of them (kDeepRadius: the deeper ones), added to the earlier rounds'.
    // The cells as one integer each, ordered as the cells' (x, y, z) triples: sorting up to 125 cells a
    // point of 4,096 as triples took 0.1–0.2 s of a wheel's offset mesh whose pass is then refused.
    const auto ny = static_cast<std::int64_t>(grid.cells(1)), nz = static_cast<std::int64_t>(grid.cells(2));
    const auto cellsAround = [&](const std::vector<Eigen::Vector3d>& points, int radius,
                                 const std::vector<std::array<int, 3>>& base) {
      std::vector<std::int64_t> ids;
      ids.reserve(base.size() + points.size() * static_cast<std::size_t>((2 * radius + 1) * (2 * radius + 1) * (2 * radius + 1)));
      for (const std::array<int, 3>& c : base) ids.push_back((c[0] * ny + c[1]) * nz + c[2]);
      for (const Eigen::Vector3d& p : points) {
        const std::array<int, 3> c = detail::cellOf(grid, p);
        for (int dx = -radius; dx <= radius; ++dx) {
          for (int dy = -radius; dy <= radius; ++dy) {
            for (int dz = -radius; dz <= radius; ++dz) {
              const std::array<int, 3> n = {c[0] + dx, c[1] + dy, c[2] + dz};
              if (n[0] >= 0 && n[1] >= 0 && n[2] >= 0 && n[0] < grid.cells(0) && n[1] < grid.cells(1) &&
                  n[2] < grid.cells(2)) {
                ids.push_back((n[0] * ny + n[1]) * nz + n[2]);
              }
            }
          }
        }
      }
      std::sort(ids.begin(), ids.end());
      ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
      std::vector<std::array<int, 3>> out(ids.size());
      for (std::size_t k = 0; k < ids.size(); ++k) {
        out[k] = {static_cast<int>(ids[k] / (ny * nz)), static_cast<int>((ids[k] / nz) % ny), static_cast<int>(ids[k] % nz)};
      }
      return out;
    };
    std::vector<std::array<int, 3>> wider = cellsAround(d.nearLimitAt, kNeckRadius, cells);
    const bool nearOnes = wider.size() <= surface.neckPassMaxCells;
    cells = nearOnes ? std::move(wider) : cellsAround(d.aboveLimitAt, kNeckRadius, cells);
    if (cells.size() > surface.neckPassMaxCells) {
      std::ostringstream line;
      line << name << ": neck pass " << round + 1 << " not run: the points beyond the limit span " << cells.size()
           << " cells (more than " << surface.neckPassMaxCells << ": not a neck)";
      progress.log(line.str());
      if (round == 0) {
        r.applied = false;
        r.tooManyCells = true;
        r.cells = cells.size();
      }
      break;
    }
    deep = cellsAround(nearOnes ? d.nearLimitAt : d.aboveLimitAt, kDeepRadius, deep);
    if (!first) first = analyzeTopology(mesh);
    PolygonizeOptions po = surfacePolygonizeOptions(field, surface);
    po.refineDeeperCells = deep;
    // First the local replacement: the level set extracted in boxes around the cells only, its faces within
    // the zone around them finished on their own and spliced into the mesh.
    if (surface.localNeckPass && surface.finish.clean && surface.finish.project &&
        surface.finish.simplify.maxTriangles == 0 && !(surface.finish.simplify.maxError > 0.0)) {
      // The zone: every round's cells, the earlier rounds' patch replaced again with the new one, so that
      // the neck is extracted in one piece (the new cells' zone alone left the bunny twin's offset 0.187%
      // off where its patch met the first round's, and the whole level set was extracted again); a round
      // with no new cells has nothing to add.
      std::vector<std::array<int, 3>> added;
      std::set_difference(cells.begin(), cells.end(), replaced.begin(), replaced.end(), std::back_inserter(added));
      std::string refused = "no cells beyond the earlier rounds'";
      if (!added.empty() && localNeckPass(evaluator, field, grid, iso, surface, minComponent, deep, cells, *first,
                                         round + 1 == kNeckRounds, po, mesh, finish, r, refused,
                                         name + ": neck pass " + std::to_string(round + 1), progress)) {
        kept = true;
        replaced = cells;
        r.cells = deep.size();
        r.local = true;
        r.localRefused.clear();
        continue;
      }
      r.localRefused = refused;
      // After a kept round that left the mesh within kWholeAgainFactor of the limit, extracting and finishing
      // the whole level set again is not worth its cost: the earlier round's mesh stays.
      if (kept && finish.deviation.max <= kWholeAgainFactor * finish.deviation.limit) {
        std::ostringstream line;
        line << name << ": neck pass " << round + 1 << ": the local replacement was not kept (" << refused
             << "): the earlier round's mesh stays (" << std::setprecision(4) << 100.0 * finish.deviation.relativeMax
             << "% of the largest side)";
        progress.log(line.str());
        break;
      }
      std::ostringstream line;
      line << name << ": neck pass " << round + 1 << ": the local replacement was not kept (" << refused
           << "): the whole level set again";
      progress.log(line.str());
      r.local = false;
    }
    FinishResult again = extractWhole(evaluator, field, grid, iso, surface, minComponent, po, progress);
    const MeshTopology after = analyzeTopology(again.meshes[0]);
    const double was = finish.deviation.relativeMax, now = again.reports[0].deviation.relativeMax;
    const bool better = again.reports[0].deviationMeasured && now < was &&
                        ((after.watertight() && after.manifold()) || !(first->watertight() && first->manifold()));
    std::ostringstream line;
    line << std::setprecision(4) << name << ": neck pass " << round + 1 << ", " << deep.size()
         << " cells refined one level more: deviation " << 100.0 * was << "% -> " << 100.0 * now << "% of the largest side, "
         << mesh.faces.rows() << " -> " << again.meshes[0].faces.rows() << " triangles, " << (better ? "kept" : "not kept");
    progress.log(line.str());
    if (!better) break;
    kept = true;
    replaced = cells;
    r.cells = deep.size();
    mesh = std::move(again.meshes[0]);
    finish = again.reports[0];
  }
  r.kept = kept;
  r.facesAfter = static_cast<std::size_t>(mesh.faces.rows());
  r.maxAfter = finish.deviation.relativeMax;
  r.seconds = secondsSince(start);
  finish.neckPass = r;
  return kept;
}

/// The interrupter of one mesh's task among several at once (finishMeshesWithNeckPass): its lines are kept
/// (and logged by the caller afterwards, in mesh order, so that the log reads as when they ran one after
/// another); the task on the calling thread polls the caller's interrupter and raises `stop` for the others,
/// which only read it (the caller's object need not be thread-safe).
class MeshTaskInterrupter : public Interrupter {
 public:
  MeshTaskInterrupter(Interrupter* outer, std::atomic<bool>& stop) : outer_(outer), stop_(stop) {}
  bool wasInterrupted(int percent) override {
    (void)percent;
    if (outer_ != nullptr && outer_->wasInterrupted(-1)) stop_.store(true);
    return stop_.load();
  }
  void message(const std::string& line) override { lines.push_back(line); }
  std::vector<std::string> lines;

 private:
  Interrupter* outer_;  // null on the other threads
  std::atomic<bool>& stop_;
};

/// finishSurfaces and then neckPass on every mesh of a duplex fit, each mesh on a thread of its own (up to
/// MeshFinishOptions::concurrentMeshes, as finishSurfaces does), so that a mesh's neck pass starts when its
/// own finishing ends, not when every mesh's has, and two neck passes run at once (a pass keeps about 1.3
/// cores busy: bunny_35k_noise0.5pct, 6.5 s of CPU in 5.1 s for its two meshes one after the other). The
/// evaluator is shared; each mesh's result is the same as alone, and each mesh's lines are logged together.
std::vector<MeshFinishReport> finishMeshesWithNeckPass(const FieldEvaluator& evaluator, const ImplicitField& field,
                                                       const GridSpec& grid, const std::vector<double>& isos,
                                                       const SurfaceOptions& surface,
                                                       const SelfCheckOptions& selfCheck, std::vector<Mesh>& meshes,
                                                       const Progress& progress) {
  const std::size_t n = meshes.size();
  std::vector<MeshFinishReport> finished(n);
  const double cell = grid.cellSize().maxCoeff();
  MeshFinishOptions one = surface.finish;
  one.concurrentMeshes = 1;
  const auto task = [&](std::size_t i, const Progress& p) {
    std::vector<Mesh> single;
    single.push_back(std::move(meshes[i]));
    FinishResult r = finishSurfaces(evaluator, field, std::move(single), {isos[i]}, cell, one, p.interrupter());
    meshes[i] = std::move(r.meshes[0]);
    finished[i] = r.reports[0];
    const std::string name = surfaceName(static_cast<int>(i));
    logFinish(name, finished[i], p);
    neckPass(evaluator, field, grid, isos[i], surface, dropFraction(selfCheck, i), meshes[i], finished[i], name, p);
  };
  const std::size_t workers = detail::workersFor(surface.finish.concurrentMeshes, n);
  progress.start("finish");
  if (workers <= 1) {
    for (std::size_t i = 0; i < n; ++i) task(i, progress);
    progress.end();
    return finished;
  }
  std::atomic<bool> stop{false};
  std::atomic<std::size_t> next{0};
  std::vector<std::vector<std::string>> lines(n);
  std::vector<std::exception_ptr> errors(n);
  // The meshes are taken in order by the workers; the calling thread's tasks poll the caller's interrupter.
  const auto work = [&](bool polls) {
    for (;;) {
      const std::size_t k = next.fetch_add(1);
      if (k >= n || stop.load()) return;
      MeshTaskInterrupter own(polls ? progress.interrupter() : nullptr, stop);
      try {
        task(k, Progress(&own));
      } catch (...) {
        errors[k] = std::current_exception();
        stop.store(true);
      }
      lines[k] = std::move(own.lines);
    }
  };
  detail::runOnWorkers(workers, work);
  for (const std::vector<std::string>& l : lines) {
    for (const std::string& line : l) progress.log(line);
  }
  // The first failure in mesh order; a task stopped only because another failed reports Cancelled.
  std::exception_ptr cancelled;
  for (const std::exception_ptr& e : errors) {
    if (!e) continue;
    try {
      std::rethrow_exception(e);
    } catch (const Cancelled&) {
      if (!cancelled) cancelled = e;
    } catch (...) {
      throw;
    }
  }
  if (cancelled) std::rethrow_exception(cancelled);
  progress.end();
  return finished;
}

/// After the fit: the surfaces, the self-check against `checkPoints`, clean-up and topology, the shell.
void extractAndFinish(const Device& device, PipelineResult& result, std::shared_ptr<const FieldEvaluator> evaluator,
                      const Points& checkPoints, const Points& checkNormals, const PipelineOptions& options,
                      const Progress& progress, Communicator* comm = nullptr) {
  PipelineReport& report = result.report;
  const FitReport& rep = report.fit;
  const Precision precision = options.fit.precision;
  auto t = Clock::now();
  std::vector<double> isos{0.0};
  isos.insert(isos.end(), rep.offsets.begin(), rep.offsets.end());
  progress.start("polygonize");
  progress.log("polygonizing " + std::to_string(isos.size()) + " level sets ...");
  SurfaceOptions surface = options.surface;
  surface.precision = precision;
  std::vector<SurfaceResult> extracted;
  std::vector<Mesh> meshes;
  if (comm != nullptr && comm->size() > 1) {
    // Every rank polygonizes a slab of the grid; rank 0 welds them and goes on alone.
    if (!evaluator) throw InvalidArgument("distributed extraction: the fit's evaluator is missing");
    DistributedExtractionReport slabs;
    extracted.push_back(extractSurfacesDistributed(*comm, *evaluator, result.fields[0], isos, surface,
                                                   progress.interrupter(), &slabs));
    meshes = std::move(extracted.back().meshes);
    report.distributedExtraction = std::move(slabs);
    if (comm->rank() != 0) return;
  } else if (!options.separate) {
    extracted.push_back(evaluator ? extractSurfaces(*evaluator, result.fields[0], isos, surface, progress.interrupter())
                                  : extractSurfaces(device, result.fields[0], isos, surface, progress.interrupter()));
    meshes = std::move(extracted.back().meshes);
  } else {
    // The separate fields share the zero field's grid cell unless the user chose one, so that both modes
    // mesh at the same resolution.
    if (surface.cell <= 0.0 && surface.resolution <= 0) {
      surface.cell = surfaceGrid(result.fields[0], isos, surface).cellSize().maxCoeff();
    }
    for (const ImplicitField& f : result.fields) {
      extracted.push_back(extractSurfaces(device, f, {0.0}, surface, progress.interrupter()));
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

  // Components below the minimum area fractions are dropped before the finishing (cleanAndSelfCheck's
  // first half); the check itself runs once, on the meshes as written (below).
  t = Clock::now();
  const std::vector<DroppedComponents> dropped = dropSmallComponents(meshes, options.selfCheck);
  const double dropSeconds = secondsSince(t);

  // Cleaning, simplification when asked, and every mesh's deviation from its level set.
  t = Clock::now();
  // The neck pass too in duplex mode (one field, one grid), each mesh's right after its finishing.
  std::vector<MeshFinishReport> finished =
      !options.separate && evaluator
          ? finishMeshesWithNeckPass(*evaluator, result.fields[0], report.grid, isos, surface, options.selfCheck,
                                     meshes, progress)
          : finishMeshes(device, result.fields, evaluator.get(), meshes, isos, options.separate,
                         first.grid.cellSize().maxCoeff(), options.surface.finish, precision, progress);
  report.secondsFinish = secondsSince(t);

  // Every fit checks its finished meshes: zero-level components without input points and offset components
  // away from |delta| are listed. (Checking the extraction's meshes before the finishing, as the first
  // version did, needed a second check whenever the neck pass replaced a mesh, and tested what is not written.)
  // Each mesh's topology is taken on a thread of its own while the self-check runs: both only read the
  // meshes, and the check leaves most of a core idle (fandisk_550k: 0.4 s of topology, serial, beside
  // 0.7 s of checking at 1.2 cores). A future's destructor waits for it, should the check throw.
  // The triangles' quality too (what `check` counts: float32-degenerate faces and slivers).
  const auto topologyOf = [&meshes] {
    std::vector<std::pair<MeshTopology, TriangleQuality>> topologies;
    for (const Mesh& m : meshes) topologies.emplace_back(analyzeTopology(m), triangleQuality(m));
    return topologies;
  };
  std::future<std::vector<std::pair<MeshTopology, TriangleQuality>>> topologies;
  try {
    topologies = std::async(std::launch::async, topologyOf);
  } catch (const std::system_error&) {
    topologies = std::async(std::launch::deferred, topologyOf);  // no thread to spare: taken below
  }
  progress.start("self-check");
  // Phantom solid left in a pocket or a narrow gap, too near the samples for the sign anchors: removed from
  // the field and the zero mesh, then checked again (docs/method.md, "Phantom repair").
  const bool repairs = options.repairPhantoms && !options.separate && evaluator &&
                       checkNormals.rows() == checkPoints.rows() && checkPoints.rows() > 0;
  SelfCheckOptions checkOptions = options.selfCheck;
  if (repairs && !(checkOptions.candidateEdges > 0.0)) checkOptions.candidateEdges = options.phantomRepair.candidateEdges;
  checkOptions.candidatesFirst = repairs;  // with candidates, the offsets are checked once, after the repair
  report.selfCheck = selfCheck(meshes, isos, checkPoints, checkOptions);
  std::vector<std::pair<MeshTopology, TriangleQuality>> topology = topologies.get();
  if (repairs && !report.selfCheck.emptyComponents.empty()) {
    PhantomRepairOptions repairOptions = options.phantomRepair;
    repairOptions.reextractMeshes = true;
    PhantomRepairResult repaired = repairPhantoms(device, precision, result.fields[0], *evaluator, checkPoints, checkNormals,
                                                  meshes, isos, report.selfCheck.emptyComponents, repairOptions);
    PhantomRepairReport& pr = repaired.report;
    // The meshes as the repair leaves them: its moves and removals applied, and the meshes it hands back
    // extracted again around the correction and spliced in (or extracted whole again when the splice is
    // refused). When both fail for a mesh the whole repair is refused (field and meshes stay as they were).
    std::vector<Mesh> next;
    std::vector<MeshFinishReport> nextFinished;
    std::vector<std::string> spliceLines;
    if (repaired.field) {
      const auto spliceStart = Clock::now();
      next = meshes;
      nextFinished = finished;
      for (std::size_t j = 0; j < repaired.moves.size() && j < next.size(); ++j) {
        for (const auto& [v, x] : repaired.moves[j]) next[j].vertices.row(v) = x.transpose();
      }
      for (std::size_t j = 0; j < repaired.removedFaces.size() && j < next.size(); ++j) {
        if (repaired.removedFaces[j].empty()) continue;
        std::vector<char> keep(static_cast<std::size_t>(next[j].faces.rows()), 1);
        for (const Index f : repaired.removedFaces[j]) keep[static_cast<std::size_t>(f)] = 0;
        next[j] = keepFaces(next[j], keep);
      }
      for (std::size_t j = 0; j < repaired.reextract.size() && j < next.size() && pr.refused.empty(); ++j) {
        if (repaired.reextract[j].empty()) continue;
        std::string why;
        const std::string name = surfaceName(static_cast<int>(j));
        if (spliceAroundRepair(*repaired.evaluator, *repaired.field, report.grid, isos[j], surface,
                               dropFraction(options.selfCheck, j), repaired.reextract[j], next[j], nextFinished[j], why,
                               name, spliceLines, progress)) {
          continue;
        }
        // The local replacement refused (armadillo_43k's offsets at δ = 0.01 and −0.02, wheel_29k's at −0.02:
        // a patch off its level set, crossing or float32-degenerate triangles in it): the whole level set of
        // the repaired field again, as the first extraction and finishing made it.
        try {
          const auto wholeStart = Clock::now();
          FinishResult again = extractWhole(*repaired.evaluator, *repaired.field, report.grid, isos[j], surface,
                                            dropFraction(options.selfCheck, j),
                                            surfacePolygonizeOptions(*repaired.field, surface), progress);
          next[j] = std::move(again.meshes[0]);
          nextFinished[j] = again.reports[0];
          neckPass(*repaired.evaluator, *repaired.field, report.grid, isos[j], surface, dropFraction(options.selfCheck, j),
                   next[j], nextFinished[j], name, progress);
          std::ostringstream line;
          line << std::setprecision(4) << "phantom repair: " << name << " extracted again whole (the local replacement: "
               << why << "), " << next[j].faces.rows() << " triangles, deviation "
               << 100.0 * nextFinished[j].deviation.relativeMax << "% of the largest side, " << secondsSince(wholeStart)
               << " s";
          spliceLines.push_back(line.str());
        } catch (const Cancelled&) {
          throw;
        } catch (const std::exception& e) {
          pr.refused = "the level set of " + name + " could not be extracted again around the correction (" + why +
                       ") nor whole (" + e.what() + ")";
        }
      }
      pr.reextractSeconds = secondsSince(spliceStart);
      if (!pr.refused.empty()) {
        pr.refusedPhantoms += pr.repaired;
        pr.repaired = pr.repairedFaces = pr.offsetFaces = pr.reextracted = 0;
        pr.maxChange = pr.maxDeviation = 0.0;
        repaired.field.reset();
        repaired.evaluator.reset();
      }
    }
    if (repaired.field) {
      result.fields[0] = std::move(*repaired.field);
      evaluator = std::move(repaired.evaluator);  // the repair's checks built it for the repaired field
      for (std::size_t j = 0; j < meshes.size(); ++j) {  // faces removed, vertices moved or extracted again
        const bool removed = j < repaired.removedFaces.size() && !repaired.removedFaces[j].empty();
        const bool moved = j < repaired.moves.size() && !repaired.moves[j].empty();
        const bool again = j < repaired.reextract.size() && !repaired.reextract[j].empty();
        if (removed || again) topology[j].first = analyzeTopology(next[j]);
        if (removed || moved || again) topology[j].second = triangleQuality(next[j]);
      }
      meshes = std::move(next);
      finished = std::move(nextFinished);
      for (const std::string& line : spliceLines) progress.log(line);
      progress.log("phantom repair: " + std::to_string(pr.repaired) + " zero-level component(s) without input points (" +
                   std::to_string(pr.repairedFaces) + " faces) removed from the field and the mesh" +
                   (pr.offsetFaces > 0 ? " with " + std::to_string(pr.offsetFaces) + " offset faces inside them" : std::string()) +
                   " (" +
                   std::to_string(pr.anchors) + " anchors, " + std::to_string(pr.keepPoints) +
                   " keep points at the finest level; vertices beside it moved by at most " + numText(pr.maxChange) +
                   " onto the level sets" +
                   (pr.reextracted > 0 ? ", " + std::to_string(pr.reextracted) + " mesh(es) extracted again around it"
                                       : std::string()) +
                   "), " + std::to_string(pr.seconds + pr.reextractSeconds) + " s");
      if (pr.refusedPhantoms > 0) {
        progress.log("phantom repair: " + std::to_string(pr.refusedPhantoms) + " candidate(s) left as they were (" +
                     pr.firstRefusal + ")");
      }
    } else if (!pr.refused.empty()) {
      progress.log("phantom repair: refused (" + pr.refused + ")");
    }
    report.phantomRepair = pr;
  }
  if (!report.selfCheck.offsetsChecked) {
    // The meshes as written, the offsets measured once (the zero level again: its repaired components are
    // gone, its kept ones moved by at most the repair's bound).
    const double firstCheck = report.selfCheck.seconds;
    report.selfCheck = selfCheck(meshes, isos, checkPoints, options.selfCheck);
    report.selfCheck.seconds += firstCheck;
  }
  for (std::size_t i = 0; i < report.selfCheck.surfaces.size(); ++i) report.selfCheck.surfaces[i].dropped = dropped[i];
  report.selfCheck.seconds += dropSeconds;
  logSelfCheck(report.selfCheck, progress);
  progress.end();

  for (std::size_t i = 0; i < meshes.size(); ++i) {
    PipelineSurface s;
    s.field = options.separate ? i : 0;
    s.iso = options.separate ? 0.0 : isos[i];
    s.offset = isos[i];
    s.topology = topology[i].first;
    s.quality = topology[i].second;
    s.mesh = std::move(meshes[i]);
    s.finish = finished[i];
    result.surfaces.push_back(std::move(s));
  }

  if (options.shell) {
    progress.start("shell");
    // The inner surface: the smallest inward offset.
    std::size_t inner = 0, inward = 0;
    for (std::size_t i = 1; i < isos.size(); ++i) {
      if (!(isos[i] > 0.0)) continue;
      ++inward;
      if (inner == 0 || isos[i] < isos[inner]) inner = i;
    }
    PipelineShell shell;
    shell.surface = inner;
    if (inward > 1) {
      shell.note = std::to_string(inward) + " inward offsets: the shell uses the smallest, " + numText(isos[inner]) +
                   " (offset" + std::to_string(inner) + ")";
      progress.log("shell: " + shell.note);
    }
    ShellOptions so = options.shellOptions;
    so.offset = isos[inner];
    so.minCavityFraction = std::max(options.selfCheck.minAreaFraction, options.selfCheck.minOffsetAreaFraction);
    const Mesh& zeroMesh = result.surfaces[0].mesh;
    const Mesh& offsetMesh = result.surfaces[inner].mesh;
    ShellResult built;
    if (so.drained()) {
      // The drained solid min(f, δ − f, holes) on the extraction's grid: away from the holes its mesh is
      // the zero and offset meshes'.
      if (!evaluator) evaluator = std::make_shared<FieldEvaluator>(device, result.fields[0], precision);
      const FieldEvaluator& ev = *evaluator;
      const FieldSampler sampler = valueSampler(ev);
      built = drainShell(sampler, report.grid, zeroMesh, offsetMesh, so, surface.polygonize, progress.interrupter());
      warnCoarseHoles(built.report, report.grid, progress);
    } else {
      built = buildShell(zeroMesh, offsetMesh, so);
    }
    shell.mesh = std::move(built.mesh);
    shell.report = std::move(built.report);
    progress.log(shellSummary(shell.report));
    if (!(shell.report.volume > 0.0) || shell.report.intersects()) {
      progress.log("warning: the shell is not a valid solid (volume <= 0 or intersecting surfaces)");
    }
    result.shell = std::move(shell);
    progress.end();
  }
}

/// The options with PipelineOptions::limits handed to every stage (when it is set).
PipelineOptions withLimits(PipelineOptions o) {
  if (o.limits.maxMemoryBytes == 0) return o;
  o.meshSampling.limits = o.limits;
  o.fit.limits = o.limits;
  o.normals.limits = o.limits;
  o.denoiseOptions.limits = o.limits;
  o.surface.polygonize.limits = o.limits;
  return o;
}

/// The extraction's grid as it will be after the fit (from the cloud's bounds and the fit's σ_M), checked
/// against the budget before the fit: a grid too large is refused before minutes of fitting.
void checkGridBeforeFit(const PointSet& points, const PipelineOptions& options) {
  const FitOptions& f = options.fit;
  const Eigen::AlignedBox3d bounds = points.bounds();
  const double side = bounds.sizes().maxCoeff();
  std::vector<double> isos{0.0};
  for (const double d : f.offsets) isos.push_back(f.offsetsRelative ? d * side : d);
  const double sigmaM = fitScales(points.positions(), f.alpha, f.levels).sigmaFinest;
  const GridSpec grid = surfaceGrid(bounds, sigmaM, isos, options.surface);
  checkPolygonizeMemory(grid, options.separate ? 1 : isos.size(), options.surface.polygonize);
}

/// Everything after the points are read: normals, merge, denoise, fit, surfaces, self-check, topology.
PipelineResult runOnPoints(const Device& device, PointCloudFile file, std::string inputName, double readSeconds,
                           const PipelineOptions& options, const Progress& progress, Clock::time_point start,
                           std::optional<MeshSampleReport> mesh = std::nullopt) {
  PipelineResult result;
  PipelineReport& report = result.report;
  report.input = std::move(inputName);
  report.mesh = std::move(mesh);
  if (report.mesh) report.meshFormat = meshFormatOf(report.input);
  report.secondsRead = readSeconds;
  const std::string& input = report.input;
  const std::string source = input.empty() ? std::string("points") : input;
  FitOptions fitOptions = options.fit;  // its smoothing set below when the points are filtered
  const Precision precision = fitOptions.precision;
  validateFinishOptions(options.surface.finish);  // before any work (simplification needs meshoptimizer)

  // Far outliers first: they would set the bounding box of everything after (docs/method.md §9). The
  // input's noise from the same k-d tree (its median is not moved by a few outliers or duplicates).
  {
    const NeighborIndex inputIndex(file.points.positions());
    report.outliers = findOutliers(file.points.positions(), options.outliers, &inputIndex);
    report.noise = estimateNoise(file.points.positions(), inputIndex);
  }
  std::string outlierHint;
  if (!report.outliers.indices.empty()) {
    const std::string what = report.outliers.describe(file.points.positions());
    if (options.removeOutliers) {
      std::vector<char> drop(file.points.size(), 0);
      for (const Index i : report.outliers.indices) drop[static_cast<std::size_t>(i)] = 1;
      const Points& p = file.points.positions();
      const Points& nrm = file.points.normals();
      Points keptP(static_cast<Eigen::Index>(file.points.size() - report.outliers.indices.size()), 3);
      Points keptN(keptP.rows(), 3);
      Eigen::Index row = 0;
      for (std::size_t i = 0; i < drop.size(); ++i) {
        if (drop[i] != 0) continue;
        keptP.row(row) = p.row(static_cast<Eigen::Index>(i));
        keptN.row(row) = nrm.rows() > 0 ? Eigen::RowVector3d(nrm.row(static_cast<Eigen::Index>(i))) : Eigen::RowVector3d::Zero();
        ++row;
      }
      file.points = PointSet(std::move(keptP), std::move(keptN));
      report.outliersRemoved = report.outliers.indices.size();
      progress.log("removed " + what);
    } else {
      outlierHint = "; " + what + ": --remove-outliers drops them";
      progress.log("warning: " + what + "; --remove-outliers drops them");
    }
  }

  if (options.estimateNormals) {
    NormalOptions normalOptions = options.normals;
    normalOptions.precision = precision;
    progress.start("normals");
    progress.log(std::string(file.report.normals ? "re-estimating" : "estimating") + " normals (k = " +
                 std::to_string(normalOptions.k) + ") ...");
    try {
      NormalResult estimated = estimateNormals(device, file.points.positions(), normalOptions, progress.interrupter());
      file.points = std::move(estimated.points);
      report.normals = estimated.report;
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(source + ": " + e.what());
    }
    const NormalReport& nr = *report.normals;
    progress.log("normals: " + std::to_string(nr.components) + " component(s), " +
                 std::to_string(nr.flippedComponents) + " flipped outward, " + std::to_string(nr.seconds) + " s");
    progress.end();
  }
  report.duplicatesMerged = file.points.mergeDuplicates();
  const bool filterPoints = options.denoise || (report.noise.noisy() && options.denoiseWhenNoisy);
  if (filterPoints && fitOptions.smoothing == 0.0) fitOptions.smoothing = options.denoiseSmoothing;
  if (report.noise.noisy() && !options.denoise) {
    report.denoisedForNoise = options.denoiseWhenNoisy;
    std::ostringstream line;
    line << std::setprecision(2) << (report.denoisedForNoise ? "" : "hint: ") << "the points scatter "
         << report.noise.ratio << " point spacings off their neighbours' planes (median of " << report.noise.samples
         << " samples; clean scans stay below " << report.noise.threshold << "): ";
    if (report.denoisedForNoise) {
      line << "filtering them (bilateral) and fitting with smoothing " << fitOptions.smoothing
           << "; --no-denoise interpolates them as they are";
    } else {
      line << "the field interpolates that noise (bumpy surfaces, small bubbles, long meshing); --denoise filters "
              "the points and fits smoothly";
    }
    progress.log(line.str());
  }
  if (filterPoints) {
    BilateralOptions filter = options.denoiseOptions;
    filter.precision = precision;
    progress.start("denoise");
    progress.log("bilateral filter ...");
    BilateralResult filtered = bilateralFilter(device, file.points, filter, progress.interrupter());
    file.points = std::move(filtered.points);
    const BilateralReport& br = filtered.report;
    progress.log("bilateral filter: sigma_s " + std::to_string(br.sigmaSpatial) + ", sigma_r " +
                 std::to_string(br.sigmaRange) + ", mean displacement " + std::to_string(br.meanDisplacement) + ", " +
                 std::to_string(br.seconds) + " s");
    progress.end();
    report.denoise = br;
  }
  try {
    checkFittable(file.points, source);  // errors name the file
  } catch (const InvalidArgument& e) {
    if (outlierHint.empty()) throw;
    throw InvalidArgument(e.what() + outlierHint);  // the outliers are the likely cause
  }
  progress.log((report.mesh ? "sampled " : "read ") + std::to_string(file.report.points) + " points from " + input + " (" +
               std::to_string(report.duplicatesMerged) + " duplicates merged) in " + std::to_string(report.secondsRead) +
               " s");
  report.read = file.report;
  report.separate = options.separate;
  report.sideTest = fitOptions.sideTest;
  report.creaseTest = fitOptions.creaseTest;
  checkGridBeforeFit(file.points, options);

  // Duplex mode: one field, every surface a level set of it. Separate mode: one field per surface, each
  // surface the 0-level of its own field (the baseline of the paper's Table 1).
  progress.start("fit");
  FitReport& rep = report.fit;
  std::shared_ptr<const FieldEvaluator> evaluator;  // the duplex fit's, reused by the extraction
  if (options.separate) {
    SeparateFitResult sep = fitSeparate(device, file.points, fitOptions, progress.interrupter());
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
    FitResult fitted = fit(device, file.points, fitOptions, progress.interrupter());
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

  // The phantom repair's winding number takes outward normals.
  const Points outward = fitOptions.normalsInward ? Points(-file.points.normals()) : file.points.normals();
  extractAndFinish(device, result, std::move(evaluator), file.points.positions(), outward, options, progress);
  report.secondsTotal = secondsSince(start);
  return result;
}

}  // namespace


bool PipelineSurface::sound() const noexcept {
  const ProjectReport& p = finish.project;
  return topology.watertight() && topology.manifold() && topology.oriented() &&
         !(p.selfIntersectionsChecked && p.selfIntersectionsLeft > 0) && quality.float32DegenerateFaces == 0 &&
         !tooManySlivers();
}

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

PipelineResult runPipeline(const Device& device, const std::string& inputPath, const PipelineOptions& given,
                           Interrupter* interrupter) {
  const auto start = Clock::now();
  const PipelineOptions options = withLimits(given);
  validateShell(options);
  const Progress progress(interrupter);
  progress.start("read");
  const InputKind kind = options.input == InputKind::Auto ? detectInputKind(inputPath) : options.input;
  PointCloudFile file;
  std::optional<MeshSampleReport> meshReport;
  if (kind == InputKind::Mesh) {
    if (options.fit.normalsInward) {
      throw InvalidArgument(inputPath + ": --normals-inward applies to clouds; the samples of a mesh carry its "
                            "outward face normals (an inside-out mesh is detected and flipped)");
    }
    const Mesh mesh = readMesh(inputPath);
    MeshSampleOptions sampling = options.meshSampling;
    if (options.estimateNormals && sampling.orientation == MeshOrientation::Require) {
      sampling.orientation = MeshOrientation::Keep;  // the face normals are replaced anyway
    }
    MeshSampleResult sampled = sampleMeshCloud(mesh, sampling, inputPath);
    const MeshSampleReport& m = sampled.report;
    std::ostringstream line;
    line << std::setprecision(4) << "mesh " << inputPath << ": " << m.topology.faces << " triangles, area " << m.area
         << ", " << (m.topology.watertight() ? "closed" : "OPEN") << ", " << m.samples << " samples (" << m.densityRule
         << " rule, spacing " << m.spacing << ")";
    progress.log(line.str());
    for (const std::string& w : m.warnings) progress.log("warning: " + w);
    file.points = std::move(sampled.points);
    file.report.format = PointFormat::Auto;
    file.report.points = file.points.size();
    file.report.normals = true;
    file.report.properties = {"x", "y", "z", "nx", "ny", "nz"};
    meshReport = std::move(sampled.report);
  } else {
    PointReadOptions readOptions;
    readOptions.requireNormals = !options.estimateNormals;
    try {
      file = readPointCloudWithReport(inputPath, readOptions);
    } catch (const InvalidArgument& e) {  // an unknown extension
      throw InvalidArgument(std::string(e.what()) + "; as a mesh: .stl, .obj or .ply with faces");
    }
  }
  const double readSeconds = secondsSince(start);
  progress.end();
  return runOnPoints(device, std::move(file), inputPath, readSeconds, options, progress, start, std::move(meshReport));
}

PipelineResult runPipeline(const Device& device, const PointSet& points, const PipelineOptions& given,
                           Interrupter* interrupter) {
  const auto start = Clock::now();
  const PipelineOptions options = withLimits(given);
  validateShell(options);
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

std::string pipelineShellName(const std::string& meshFormat) { return "shell." + meshFormat; }

std::vector<std::string> pipelineFieldNames(const PipelineResult& result) {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < result.fields.size(); ++i) {
    names.push_back(i == 0 ? std::string("field.dpxf") : "field_offset" + std::to_string(i) + ".dpxf");
  }
  return names;
}

namespace {

/// Runs every task, one thread each (this thread takes the last; a task whose thread cannot be started
/// runs here too), and rethrows the first task's exception in list order after all have stopped.
void runConcurrently(const std::vector<std::function<void()>>& tasks) {
  std::vector<std::exception_ptr> errors(tasks.size());
  const auto run = [&](std::size_t i) {
    try {
      tasks[i]();
    } catch (...) {
      errors[i] = std::current_exception();
    }
  };
  std::vector<std::thread> threads;
  threads.reserve(tasks.size());  // no reallocation below: only a thread's own start can fail there
  std::size_t here = 0;  // tasks [here, size) run on this thread
  for (; here + 1 < tasks.size(); ++here) {
    try {
      threads.emplace_back(run, here);
    } catch (const std::system_error&) {
      break;  // no thread to spare: the rest run here
    }
  }
  for (std::size_t i = here; i < tasks.size(); ++i) run(i);
  for (std::thread& th : threads) th.join();
  for (const std::exception_ptr& e : errors) {
    if (e) std::rethrow_exception(e);
  }
}

}  // namespace

void writePipelineOutputs(const PipelineResult& result, StagedFolder& folder, const std::string& meshFormat) {
  if (meshFormat != "ply" && meshFormat != "obj" && meshFormat != "stl" && meshFormat != "3mf") {
    throw InvalidArgument("mesh format must be ply, obj, stl or 3mf, not '" + meshFormat + "'");
  }
  const auto t = Clock::now();
  // The files are written at once, a thread each: most of a write is the serialisation and the kernel's
  // copy into fresh page-cache pages, both CPU work (fandisk_550k: 0.6 s for the 104 MB field and 0.3 s
  // for each mesh, one after the other). The first error in file order is thrown once every writer has
  // stopped; the staged folder is then not committed, so nothing half-written is left. The staged paths
  // are taken here, in order (StagedFolder::path records each name and is not thread-safe).
  std::vector<std::function<void()>> writers;
  const std::vector<std::string> meshNames = pipelineMeshNames(result, meshFormat);
  for (std::size_t i = 0; i < meshNames.size(); ++i) {
    writers.emplace_back([&mesh = result.surfaces[i].mesh, path = folder.path(meshNames[i])] { writeMesh(path, mesh); });
  }
  if (result.shell) {
    writers.emplace_back([&mesh = result.shell->mesh, path = folder.path(pipelineShellName(meshFormat))] {
      writeMesh(path, mesh);
    });
  }
  const std::vector<std::string> fieldNames = pipelineFieldNames(result);
  for (std::size_t i = 0; i < fieldNames.size(); ++i) {
    writers.emplace_back([&field = result.fields[i], path = folder.path(fieldNames[i])] { field.save(path); });
  }
  runConcurrently(writers);
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

double defaultMinComponent(double iso) {
  return iso == 0.0 ? 0.0 : PipelineOptions::defaultSelfCheck().minOffsetAreaFraction;
}

MeshPipelineResult runMeshPipeline(const Device& device, const ImplicitField& field, double iso,
                                   const SurfaceOptions& options, double minComponent, Interrupter* interrupter) {
  const Progress progress(interrupter);
  validateFinishOptions(options.finish);
  progress.start("polygonize");
  MeshPipelineResult r;
  if (field.levels().empty()) throw InvalidArgument("surface extraction: the field has no levels");
  const FieldEvaluator evaluator(device, field, options.precision);
  r.extraction = extractSurfaces(evaluator, field, {iso}, options, progress.interrupter());
  progress.end();
  DropResult kept = dropSmallComponents(r.extraction.meshes[0], minComponent);
  r.mesh = std::move(kept.mesh);
  r.dropped = kept.dropped;
  r.extraction.meshes.clear();
  if (r.dropped.components > 0) {
    std::ostringstream line;
    line << std::setprecision(4) << "dropped " << r.dropped.components << " component(s) below " << minComponent
         << " of the mesh's area (" << r.dropped.faces << " faces, " << 100.0 * r.dropped.areaFraction
         << "% of the area)";
    progress.log(line.str());
  }
  progress.start("finish");
  std::vector<Mesh> one;
  one.push_back(std::move(r.mesh));
  FinishResult finished = finishSurfaces(evaluator, field, std::move(one), {iso},
                                         r.extraction.grid.cellSize().maxCoeff(), options.finish,
                                         progress.interrupter());
  r.mesh = std::move(finished.meshes[0]);
  r.finish = finished.reports[0];
  logFinish("mesh", r.finish, progress);
  neckPass(evaluator, field, r.extraction.grid, iso, options, minComponent, r.mesh, r.finish, "mesh", progress);
  progress.end();
  r.topology = analyzeTopology(r.mesh);
  return r;
}

ShellPipelineResult runShellPipeline(const Device& device, const ImplicitField& field, const ShellOptions& options,
                                     const SurfaceOptions& surface, double minComponent, Interrupter* interrupter) {
  const double delta = options.offset;
  if (!(delta > 0.0) || !std::isfinite(delta)) {
    throw InvalidArgument("--shell needs --iso D with D > 0: the inward offset of the inner surface (got " +
                          numText(delta) + ")");
  }
  if (!(minComponent >= 0.0 && minComponent < 1.0)) {
    throw InvalidArgument("--min-component must be an area fraction in [0, 1)");
  }
  const Progress progress(interrupter);
  ShellPipelineResult r;
  const std::vector<double>& fitted = field.offsets();
  if (std::find(fitted.begin(), fitted.end(), delta) == fitted.end()) {
    std::string list;
    for (double d : fitted) list += (list.empty() ? "" : ", ") + numText(d);
    r.note = "the field was fitted with the offsets " + (list.empty() ? std::string("(none)") : list) + "; " +
             numText(delta) + " is not one of them, so the inner surface is only near that distance";
    progress.log("note: " + r.note);
  }
  progress.start("polygonize");
  const FieldEvaluator evaluator(device, field, surface.precision);
  r.extraction = extractSurfaces(evaluator, field, {0.0, delta}, surface, progress.interrupter());
  progress.end();
  const double offsetFraction = std::max(minComponent, PipelineOptions::defaultSelfCheck().minOffsetAreaFraction);
  DropResult zero = dropSmallComponents(r.extraction.meshes[0], minComponent);
  DropResult offset = dropSmallComponents(r.extraction.meshes[1], offsetFraction);
  r.extraction.meshes.clear();
  r.droppedZero = zero.dropped;
  r.droppedOffset = offset.dropped;
  // The two surfaces finished as fit finishes them (cleaned, projected onto their level sets), so that
  // `mesh --shell` and `fit --shell` join the same meshes.
  progress.start("finish");
  std::vector<Mesh> two;
  two.push_back(std::move(zero.mesh));
  two.push_back(std::move(offset.mesh));
  FinishResult finished = finishSurfaces(evaluator, field, std::move(two), {0.0, delta},
                                         r.extraction.grid.cellSize().maxCoeff(), surface.finish,
                                         progress.interrupter());
  zero.mesh = std::move(finished.meshes[0]);
  offset.mesh = std::move(finished.meshes[1]);
  logFinish("zero", finished.reports[0], progress);
  logFinish("offset", finished.reports[1], progress);
  progress.end();
  progress.start("shell");
  ShellOptions so = options;
  so.minCavityFraction = offsetFraction;
  if (so.drained()) {
    const FieldSampler sampler = valueSampler(evaluator);
    r.shell = drainShell(sampler, r.extraction.grid, zero.mesh, offset.mesh, so, surface.polygonize,
                         progress.interrupter());
    warnCoarseHoles(r.shell.report, r.extraction.grid, progress);
  } else {
    r.shell = buildShell(zero.mesh, offset.mesh, so);
  }
  progress.log(shellSummary(r.shell.report));
  progress.end();
  return r;
}

PipelineResult runDistributedPipeline(const Device& device, Communicator& comm, const std::string& inputPath,
                                      const PipelineOptions& options, const DistributedOptions& distributed,
                                      Interrupter* interrupter) {
  const auto start = Clock::now();
  const Progress progress(interrupter);
  const auto unsupported = [&](bool on, const char* what) {
    if (on) throw InvalidArgument(std::string(what) + " is not supported by the distributed fit yet (run without --distributed)");
  };
  unsupported(options.separate, "--separate");
  unsupported(options.estimateNormals, "--estimate-normals");
  unsupported(options.denoise, "--denoise");
  unsupported(options.removeOutliers, "--remove-outliers");
  unsupported(options.shell, "--shell");
  unsupported(options.fit.offsetCorrection, "--offset-correction");
  validateFinishOptions(options.surface.finish);
  const InputKind kind = options.input == InputKind::Auto ? detectInputKind(inputPath) : options.input;
  std::string ext = inputPath.size() >= 4 ? inputPath.substr(inputPath.size() - 4) : std::string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  if (kind == InputKind::Mesh || ext != ".ply") {
    throw InvalidArgument(inputPath + ": the distributed fit reads PLY clouds (each rank its own rows)");
  }

  // Each rank reads its own rows: [r·N/P, (r+1)·N/P).
  progress.start("read");
  const auto fileRows = static_cast<std::uint64_t>(plyVertexCount(inputPath));
  const auto p = static_cast<std::uint64_t>(comm.size()), r = static_cast<std::uint64_t>(comm.rank());
  const std::uint64_t first = fileRows * r / p, last = fileRows * (r + 1) / p;
  PointCloudFile file = readPlyVertexRows(inputPath, static_cast<std::int64_t>(first), static_cast<std::int64_t>(last - first));
  const double readSeconds = secondsSince(start);
  progress.end();

  PipelineResult result;
  PipelineReport& report = result.report;
  report.input = inputPath;
  report.secondsRead = readSeconds;
  report.read = file.report;
  report.read.points = static_cast<std::size_t>(fileRows);
  report.sideTest = options.fit.sideTest;
  report.creaseTest = options.fit.creaseTest;
  DistributedReport drep;
  progress.start("partition");
  const DistributedPoints owned = partitionPoints(comm, file.points, static_cast<std::int64_t>(first), fileRows, drep, distributed.blocks);
  file.points = PointSet();
  report.duplicatesMerged = static_cast<std::size_t>(fileRows) -
      static_cast<std::size_t>(comm.allreduce(static_cast<std::int64_t>(owned.points.size()), ReduceOp::Sum));
  progress.log("partition: " + std::to_string(comm.size()) + (comm.size() == 1 ? " rank, " : " ranks, ") +
               (drep.blocks != comm.size() ? std::to_string(drep.blocks) + " blocks, " : std::string()) +
               std::to_string(fileRows) + " rows, " +
               (drep.ownedOnce ? "every row owned once" : "ROWS NOT OWNED ONCE"));
  progress.end();
  if (!drep.ownedOnce) throw InvalidArgument(inputPath + ": the partition lost or duplicated rows (internal error)");

  progress.start("fit");
  Points checkPoints;
  FitResult fitted = fitDistributed(device, comm, owned, options.fit, distributed, drep, &checkPoints, progress.interrupter());
  report.fit = std::move(fitted.report);
  report.fit.duplicatesMerged = report.duplicatesMerged;
  report.distributed = std::move(drep);
  result.fields.push_back(std::move(fitted.field));
  progress.end();
  extractAndFinish(device, result, std::move(fitted.evaluator), checkPoints, Points(0, 3), options, progress, &comm);
  report.secondsTotal = secondsSince(start);
  return result;
}

}  // namespace duplexfit
