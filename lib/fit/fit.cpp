// The duplex-fit pipeline (docs/method.md appendix): normalise to the unit box, build the hierarchy, and for
// each level generate the constraints, assemble Φ_k + λ_k I, take b = t − f_{k−1}(C) from the field so far
// (evaluated on the device), solve by PCG on the device, and append the level. Then measure E_0 and E_δ.
#include "duplexfit/fit.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/wendland.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/winding.hpp"
#include "field/wendland_detail.hpp"
#include "fit/anchors.hpp"
#include "fit/constraints.hpp"
#include "fit/fit_detail.hpp"
#include "fit/hierarchy.hpp"
#include "fit/partition.hpp"
#include "spatial/disk_distance.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

using detail::FitWork;
using detail::LevelInterrupter;
using detail::stageStart;

void report(Interrupter* interrupter, const FitEvent& event, const FitWork* work = nullptr) {
  if (interrupter == nullptr) return;
  interrupter->fitEvent(event);
  int percent = -1;
  if (work != nullptr) {
    percent = event.stage == FitStage::Errors ? 100 : work->percent(event.level, stageStart(event.stage));
  }
  if (interrupter->wasInterrupted(percent)) {
    throw Cancelled(std::string("fit cancelled during ") + fitStageName(event.stage));
  }
}

constexpr const char* kStageNames[] = {"start",    "hierarchy",  "constraints", "assembly", "solve",
                                       "residual", "correction", "errors",      "other"};

}  // namespace

void detail::checkFitOptions(const FitOptions& o) {
  auto bad = [](const std::string& what) { throw InvalidArgument("fit options: " + what); };
  if (!(o.validityTolerance >= 0.0 && o.validityTolerance < 1.0)) bad("validityTolerance must be in [0, 1)");
  if (o.levels < 0 || o.levels > 24) bad("levels must be between 0 (automatic) and 24");
  if (!(o.alpha > 0.0) || !std::isfinite(o.alpha)) bad("alpha must be positive");
  if (!(o.smoothing >= 0.0) || !std::isfinite(o.smoothing)) bad("smoothing must be >= 0");
  if (!(o.fitTolerance >= 0.0) || !std::isfinite(o.fitTolerance)) bad("fitTolerance must be >= 0");
  if (!(o.mergeDistance >= 0.0 && o.mergeDistance < 0.5)) bad("mergeDistance must be in [0, 0.5)");
  if (!(o.levelTolerance >= 0.0) || !std::isfinite(o.levelTolerance)) bad("levelTolerance must be >= 0");
  if (!(o.coarseTolerance >= 0.0 && o.coarseTolerance < 1.0)) bad("coarseTolerance must be in [0, 1)");
  if (o.blockSize < 1 || o.blockSize > 256) bad("blockSize must be in [1, 256]");
  if (!(o.fsaiThreshold >= 0.0 && o.fsaiThreshold <= 1.0)) bad("fsaiThreshold must be in [0, 1] (--fsai-threshold)");
  if (o.fsaiMaxNeighbours < 0 || o.fsaiMaxNeighbours > 64) bad("fsaiMaxNeighbours must be in [0, 64]");
  if (!(o.overshootSpacings > 0.0 && o.overshootSpacings <= 100.0)) bad("overshootSpacings must be in (0, 100] (--overshoot-spacings)");
  if (o.overshootRounds < 0 || o.overshootRounds > 16) bad("overshootRounds must be in [0, 16] (--overshoot-rounds)");
  // 0 iterations would leave every level's weights at 0: empty meshes that look like a finished fit.
  if (o.solver.maxIterations < 1) bad("solver.maxIterations must be at least 1 (--max-iterations)");
  for (double d : o.offsets) {
    if (!std::isfinite(d)) bad("offsets must be finite");
  }
}

detail::OvershootCandidates detail::overshootCandidates(const Points& points, const Points& normals,
                                                        const std::vector<Eigen::Index>& rows, double d, int offSide) {
  OvershootCandidates c;
  for (const double s : {-1.0, 1.0}) {
    if (!(offSide == 2 || (offSide == -1 && s < 0.0) || (offSide == 1 && s > 0.0))) continue;
    for (const Eigen::Index i : rows) {
      if (normals.row(i).squaredNorm() == 0.0) continue;
      c.source.push_back(i);
      c.toward.push_back(s);
    }
  }
  c.q.resize(static_cast<Eigen::Index>(c.source.size()), 3);
  for (std::size_t r = 0; r < c.source.size(); ++r) {
    c.q.row(static_cast<Eigen::Index>(r)) = points.row(c.source[r]) + c.toward[r] * d * normals.row(c.source[r]);
  }
  c.added.assign(c.source.size(), 0);
  return c;
}

std::vector<std::size_t> detail::overshootSites(const FieldEvaluator& evaluator, OvershootCandidates& c,
                                                const NeighborIndex& index, double d) {
  std::vector<std::size_t> sites;
  if (c.source.empty()) return sites;
  const Eigen::VectorXd f = evaluator.evaluateNormalized(c.q);
  std::vector<std::size_t> failing;
  for (std::size_t r = 0; r < c.source.size(); ++r) {
    if (!c.added[r] && c.toward[r] * f[static_cast<Eigen::Index>(r)] < 0.5 * d) failing.push_back(r);
  }
  if (failing.empty()) return sites;
  Points fq(static_cast<Eigen::Index>(failing.size()), 3);
  std::vector<Index> exclude(failing.size());
  for (std::size_t j = 0; j < failing.size(); ++j) {
    fq.row(static_cast<Eigen::Index>(j)) = c.q.row(static_cast<Eigen::Index>(failing[j]));
    exclude[j] = static_cast<Index>(c.source[failing[j]]);
  }
  const NeighborLists other = index.anyOtherWithin(fq, exclude, std::vector<double>(failing.size(), d));
  for (std::size_t j = 0; j < failing.size(); ++j) {
    if (other.count(j) == 0) {
      sites.push_back(failing[j]);
      c.added[failing[j]] = 1;
    }
  }
  return sites;
}

// The typical sample spacing: the square root of the median point area.
double detail::medianSpacing(const Eigen::VectorXd& areas) {
  if (areas.size() == 0) return 0.0;
  std::vector<double> a(areas.data(), areas.data() + areas.size());
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
  return std::sqrt(std::max(0.0, a[a.size() / 2]));
}

detail::ConstraintOptions detail::levelConstraintOptions(const FitOptions& options, const std::vector<double>& deltas,
                                                        double sigma, int level, int levels, int offSurfaceSide,
                                                        Interrupter* interrupter) {
  ConstraintOptions co;
  co.interrupter = interrupter;
  co.offsets = deltas;
  co.offSurfaceDistance = sigma / 10.0;
  co.offSurfaceSide = offSurfaceSide;
  co.validityTolerance = options.validityTolerance;
  co.mergeDistance = options.mergeDistance * sigma;
  co.sigma = sigma;
  co.dropZeroNormalPoints = options.dropZeroNormalPoints;
  co.tangentSideTest = options.sideTest;
  co.creaseTest = options.creaseTest && level > levels - kCreaseTestLevels;
  co.creaseRadiusCap = 2.0 * sigma;
  co.medial = options.medialConstraints;
  return co;
}

SolverOptions detail::levelSolverOptions(const FitOptions& options, bool finest) {
  SolverOptions so = options.solver;
  if (so.absoluteTolerance == 0.0) so.absoluteTolerance = options.levelTolerance;
  if (!finest && options.coarseTolerance > 0.0) so.relativeTolerance = options.coarseTolerance;
  return so;
}

std::string detail::preconditionerName(const FitOptions& options) {
  switch (options.preconditioner) {
    case PreconditionerKind::Fsai: return FsaiPreconditioner::describe(options.fsaiThreshold, options.fsaiMaxNeighbours);
    case PreconditionerKind::BlockJacobi: return BlockJacobiPreconditioner::describe(options.blockSize);
    case PreconditionerKind::Jacobi: return "jacobi";
  }
  return "jacobi";
}

SolveStats detail::solveLevelSystem(const Device& device, const CsrMatrix& a, const Eigen::VectorXd& b,
                                    const FitOptions& options, bool finest, Eigen::VectorXd& weights,
                                    Interrupter* monitor, DeviceCsr* buffers, DeviceCsr* assembled) {
  if (b.size() == 0) {
    weights.resize(0);
    SolveStats none;
    none.converged = true;
    none.reason = StopReason::Converged;
    return none;
  }
  DeviceCsr m = assembled != nullptr ? std::move(*assembled)
                : buffers != nullptr  ? DeviceCsr::upload(device, a, options.precision, std::move(*buffers))
                                      : DeviceCsr::upload(device, a, options.precision);
  const DeviceVector db = DeviceVector::upload(device, b, options.precision);
  DeviceVector x(device, static_cast<std::size_t>(b.size()), options.precision);
  std::unique_ptr<Preconditioner> pre;
  if (options.preconditioner == PreconditionerKind::Fsai) {
    // An upload validated `a` and kept its diagonal: the set-up takes both from it. A matrix assembled on
    // the device comes with no host validation: the FSAI set-up validates it.
    pre = assembled != nullptr ? std::make_unique<FsaiPreconditioner>(device, a, options.precision, options.fsaiThreshold,
                                                                     options.fsaiMaxNeighbours)
                               : std::make_unique<FsaiPreconditioner>(m, a, options.fsaiThreshold, options.fsaiMaxNeighbours);
  } else if (options.preconditioner == PreconditionerKind::BlockJacobi) {
    pre = std::make_unique<BlockJacobiPreconditioner>(device, a, options.precision, options.blockSize);
  } else {
    pre = std::make_unique<JacobiPreconditioner>(m);
  }
  const SolverOptions so = levelSolverOptions(options, finest);
  SolveStats stats = solveCg(m, db, x, so, pre.get(), monitor);
  weights = x.download();
  // A float solve can stall just above an absolute tolerance near float's own rounding of b − A x (a small
  // coarse level asked for 1e-6 by --coarse-tol, say): refine in mixed precision. The residual in double on
  // the host, a float solve for the correction (whose rounding scales with the small residual), the sum
  // in double; at most two corrections, the statistics from the last residual in double.
  for (int round = 0; stats.reason == StopReason::Stagnated && options.precision == Precision::Float; ++round) {
    const Eigen::VectorXd r = b - a.multiply(weights);
    const double bnorm = b.norm(), rnorm = r.norm();
    stats.relativeResidual = rnorm / bnorm;
    stats.maxResidual = r.lpNorm<Eigen::Infinity>();
    const double target = stats.tolerance * bnorm;
    if (rnorm <= target || (so.absoluteTolerance > 0.0 && stats.maxResidual <= so.absoluteTolerance)) {
      stats.reason = StopReason::Converged;
      stats.converged = true;
      break;
    }
    if (round == 2) break;
    SolverOptions correction = so;
    correction.relativeTolerance = std::min(0.5, target / rnorm);
    const DeviceVector dr = DeviceVector::upload(device, r, options.precision);
    DeviceVector dx(device, static_cast<std::size_t>(r.size()), options.precision);
    const SolveStats more = solveCg(m, dr, dx, correction, pre.get(), monitor);
    stats.iterations += more.iterations;
    stats.seconds += more.seconds;
    if (more.reason == StopReason::Cancelled) {
      stats.reason = more.reason;
      break;
    }
    weights += dx.download();
  }
  if (buffers != nullptr) *buffers = std::move(m);
  return stats;
}

bool detail::assemblesOnDevice(const Device& device, const FitOptions& options) {
  if (!deviceAssemblyAvailable(device)) return false;
  switch (options.assembly) {
    case AssemblyPlace::Host: return false;
    case AssemblyPlace::Device: return true;
    case AssemblyPlace::Auto: return device.info().type != DeviceType::Cpu;
  }
  return false;
}

namespace {

// A level's report plus its solved weights (moved into the field).
struct LevelWork : LevelReport {
  Eigen::VectorXd weights;
};

}  // namespace

const char* fitStageName(FitStage stage) noexcept {
  const auto i = static_cast<std::size_t>(stage);
  return i < std::size(kStageNames) ? kStageNames[i] : "other";
}

const char* preconditionerKindName(PreconditionerKind kind) noexcept {
  switch (kind) {
    case PreconditionerKind::Fsai: return "fsai";
    case PreconditionerKind::BlockJacobi: return "block-jacobi";
    case PreconditionerKind::Jacobi: return "jacobi";
  }
  return "fsai";
}

const char* assemblyPlaceName(AssemblyPlace place) noexcept {
  switch (place) {
    case AssemblyPlace::Auto: return "auto";
    case AssemblyPlace::Host: return "host";
    case AssemblyPlace::Device: return "device";
  }
  return "auto";
}

AssemblyPlace parseAssemblyPlace(const std::string& text) {
  if (text == "auto") return AssemblyPlace::Auto;
  if (text == "host") return AssemblyPlace::Host;
  if (text == "device") return AssemblyPlace::Device;
  throw InvalidArgument("assembly: '" + text + "' is none of 'auto', 'host' and 'device'");
}

PreconditionerKind parsePreconditionerKind(const std::string& text) {
  if (text == "fsai") return PreconditionerKind::Fsai;
  if (text == "block-jacobi" || text == "block_jacobi") return PreconditionerKind::BlockJacobi;
  if (text == "jacobi") return PreconditionerKind::Jacobi;
  throw InvalidArgument("preconditioner: '" + text + "' is none of 'fsai', 'block-jacobi' and 'jacobi'");
}

const char* offSurfaceSideName(OffSurfaceSide side) noexcept {
  switch (side) {
    case OffSurfaceSide::Outside: return "outside";
    case OffSurfaceSide::Inside: return "inside";
    case OffSurfaceSide::None: return "none (offsets on both sides)";
    case OffSurfaceSide::Both: return "both sides (no offsets)";
  }
  return "outside";
}

FitScales fitScales(const Points& positions, double alpha, int levels) {
  if (positions.rows() == 0) throw InvalidArgument("fitScales: no points");
  if (!positions.allFinite()) throw InvalidArgument("fitScales: a coordinate is not finite");
  if (!(alpha > 0.0) || !std::isfinite(alpha)) throw InvalidArgument("fitScales: alpha must be positive and finite");
  FitScales s;
  const detail::HierarchyBox box = detail::hierarchyBox(positions);
  s.diagonal = box.diagonal;
  s.sigma1 = alpha * box.diagonal;
  s.sigma0 = detail::adaptiveSigma0(positions, box);
  s.levels = levels > 0 ? levels : detail::levelCount(s.sigma1, s.sigma0);
  s.sigmaFinest = s.sigma1 / std::pow(2.0, s.levels - 1);
  return s;
}

double estimateLevelBytes(std::size_t centres, std::size_t nonZeros, const FitOptions& options) {
  const double s = options.precision == Precision::Double ? 8.0 : 4.0;
  const double n = static_cast<double>(centres), z = static_cast<double>(nonZeros);
  // CSR: host (int32 column, double value) and device (int32 column, s-byte value), row pointers on both.
  const double csr = z * (12.0 + 4.0 + s) + 8.0 * (n + 1.0);
  // Block Jacobi: the inverted blocks on the host (double) and the device. FSAI: G and Gᵀ on the host
  // (int32 column, double value) and the device, row pointers on both, and one more device vector; its
  // rows are counted at 8 entries (about 5 on the shared clouds at the default threshold).
  const double fsaiEntries = n * std::min(8.0, std::max(0, options.fsaiMaxNeighbours) + 1.0);
  const double blocks = options.preconditioner == PreconditionerKind::BlockJacobi
                            ? n * static_cast<double>(std::max(1, options.blockSize)) * (8.0 + s)
                        : options.preconditioner == PreconditionerKind::Fsai
                            ? 2.0 * (fsaiEntries * (12.0 + 4.0 + s) + 8.0 * (n + 1.0)) + n * s
                            : n * s;
  // CG: six device vectors; host: centres (24 B), targets, f_{k-1}, b, weights (8 B each).
  const double vectors = n * (6.0 * s + 24.0 + 4.0 * 8.0);
  return csr + blocks + vectors;
}

FitResult fit(const Device& device, const PointSet& points, const FitOptions& options,
              Interrupter* interrupter) {
  const auto start = Clock::now();
  detail::checkFitOptions(options);
  checkFittable(points, "input cloud");
  device.requirePrecision(options.precision);

  FitReport rep;
  rep.device = device.description();
  rep.deviceTuning = device.tuning().describe();
  rep.precision = precisionName(options.precision);
  rep.preconditioner = detail::preconditionerName(options);
  rep.inputPoints = points.size();
  rep.zeroNormals = points.zeroNormals();

  // Normalise: centre the bounding box and scale its largest side to 1 (float-safe coordinates).
  const Eigen::AlignedBox3d bounds = points.bounds();
  const double side = bounds.sizes().maxCoeff();
  Normalization norm;
  norm.centre = bounds.center();
  norm.scale = 1.0 / side;
  // The points in the Morton order of their 63-bit keys over the hierarchy box (ties in the cloud's order; the
  // distributed fit orders each block's points so, and one rank reproduces this fit): every per-point pass
  // of the fit (the winding number, each level's cell centroids, the constraints' validity and medial
  // searches, the overshoot check, E_0) then reads the k-d tree, the field and the point arrays in space
  // order, whatever order the cloud came in (Poisson-disk and uniform samples, many tools' output, are in
  // random order). Nothing the fit returns refers to a point by its index.
  Points u, nu;
  {
    const Points normalised = (norm.scale * (points.positions().rowwise() - norm.centre.transpose())).eval();
    const std::vector<Eigen::Index> order = detail::mortonOrder(normalised, detail::hierarchyBox(normalised));
    u = normalised(order, Eigen::all);
    nu = (options.normalsInward ? 1.0 : -1.0) * points.normals()(order, Eigen::all);
  }

  rep.smoothing = options.smoothing;
  // Offsets in input units (report) and normalised units (fit).
  std::vector<double> deltas;
  rep.offsets = detail::worldOffsets(options.offsets, options.offsetsRelative, side);
  for (const double world : rep.offsets) deltas.push_back(world * norm.scale);
  const bool inward = std::any_of(deltas.begin(), deltas.end(), [](double d) { return d > 0; });
  const bool outward = std::any_of(deltas.begin(), deltas.end(), [](double d) { return d < 0; });
  // Off-surface points go on the side without offsets (§3.2); none when offsets cover both sides.
  const int offSide = inward && outward ? 0 : inward ? -1 : outward ? 1 : 2;
  rep.offSurfaceSide = offSide == 0    ? OffSurfaceSide::None
                       : offSide == -1 ? OffSurfaceSide::Outside
                       : offSide == 1  ? OffSurfaceSide::Inside
                                       : OffSurfaceSide::Both;

  // Hierarchy (§4).
  auto t = Clock::now();
  report(interrupter, {FitStage::Hierarchy, 0, 0, 0, 0.0, "building the octree"});
  const detail::HierarchyBox box = detail::hierarchyBox(u);
  const double sigma1 = options.alpha * box.diagonal;
  const double sigma0 = detail::adaptiveSigma0(u, box);
  const int levels = options.levels > 0 ? options.levels : detail::levelCount(sigma1, sigma0);
  rep.sigma0 = sigma0 / norm.scale;
  rep.sigma1 = sigma1 / norm.scale;
  rep.levels = levels;
  rep.secondsHierarchy = secondsSince(t);
  FitWork work(levels, u.rows(), deltas.size());
  {
    // The finest level's centres are the input points with their offset and off-surface companions (fewer
    // once invalid ones are dropped); each row has at least its diagonal. Plus the input's own arrays, the
    // winding number's and the k-d tree's (about 200 bytes a point).
    const std::size_t companions = deltas.size() + (offSide == 0 ? 0 : 1);
    const std::size_t centres = static_cast<std::size_t>(u.rows()) * (1 + companions);
    const double bytes = estimateLevelBytes(centres, centres, options) + 200.0 * static_cast<double>(u.rows());
    requireMemory(options.limits, "fit",
                  bytes, "the finest level (" + std::to_string(u.rows()) + " points with " + std::to_string(companions) +
                             " companion(s) each: up to " + std::to_string(centres) + " centres)",
                  "fit a sparser cloud (or fewer --sample-points of a mesh input) or fewer offsets");
  }

  // Sign anchors: the winding number of the input cloud (outward normals) and an index for distances.
  std::unique_ptr<WindingNumber> winding;
  std::unique_ptr<NeighborIndex> inputIndex;
  double spacing = 0.0;
  const int lastAnchorLevel = options.signAnchors ? levels - std::max(0, options.anchorSkipFinest) : 0;
  if (lastAnchorLevel >= 1) {
    t = Clock::now();
    report(interrupter, {FitStage::Hierarchy, 0, 0, 0, 0.0, "winding number"});
    const Points outwardNormals = -nu;
    // One k-d tree of the cloud for the point areas and the anchors' searches (it was built twice:
    // fandisk_550k, about 0.2 s of a serial build).
    inputIndex = std::make_unique<NeighborIndex>(u);
    const WindingOptions windingOptions;
    winding = std::make_unique<WindingNumber>(
        u, outwardNormals, estimatePointAreas(u, outwardNormals, windingOptions.areaNeighbors, *inputIndex),
        windingOptions);
    spacing = detail::medianSpacing(winding->areas());
    rep.secondsWinding = secondsSince(t);
  }
  double maxOffset = 0.0;
  for (const double d : deltas) maxOffset = std::max(maxOffset, std::abs(d));
  Eigen::AlignedBox3d anchorBox(box.min, box.max);
  anchorBox.min().array() -= 0.1 + maxOffset;
  anchorBox.max().array() += 0.1 + maxOffset;

  // The last level's matrix, on the host and on the device, whose arrays and buffers the next level's fills
  // where they are large enough (the finest level's matrix has about as many non-zeros as the one before:
  // fandisk_550k 42.4M after 43.2M), so that its pages are not paid for again.
  CsrMatrix levelMatrix;
  DeviceCsr levelBuffers;
  // The level matrices on the device (FitOptions::assembly); a level whose grid table would be too large
  // is assembled on the host and uploaded.
  const bool assembleOnDevice = detail::assemblesOnDevice(device, options);
  int levelsOnDevice = 0, levelsOnHost = 0;
  // Assembles Φ + λI for `centres`, solves it by PCG on the device from b, fills the level report (non-zeros,
  // solve statistics, times) and leaves the weights in lr.weights; returns the matrix.
  auto solveLevel = [&](const Points& centres, double sigma, double lambda, const Eigen::VectorXd& b, int k,
                        LevelWork& lr) {
    auto t0 = Clock::now();
    report(interrupter, {FitStage::Assembly, k, levels, 0, 0.0, std::to_string(centres.rows()) + " centres"}, &work);
    const detail::NonZeroCheck budget = [&](std::size_t nonZeros) {
      std::ostringstream what;
      what.precision(3);
      what << "level " << k << " of " << levels << " (" << centres.rows() << " centres, about "
           << static_cast<double>(nonZeros) << " non-zeros)";
      requireMemory(options.limits, "fit", estimateLevelBytes(static_cast<std::size_t>(centres.rows()), nonZeros, options),
                    what.str(), "fit a sparser cloud (or fewer --sample-points of a mesh input), or fewer offsets");
    };
    CsrMatrix a;
    DeviceCsr assembled;
    bool onDevice = false;
    if (assembleOnDevice) {
      detail::DeviceAssembly da = detail::assembleOnDevice(device, options.precision, centres, sigma, lambda, budget,
                                                           interrupter, detail::CellGrid::kDefaultMaxCells,
                                                           &levelMatrix, &levelBuffers);
      a = std::move(da.host);
      assembled = std::move(da.device);
      onDevice = da.onDevice;
    } else {
      a = detail::assembleWendland(centres, sigma, lambda, budget, interrupter, detail::CellGrid::kDefaultMaxCells,
                                   &levelMatrix);
    }
    (onDevice ? levelsOnDevice : levelsOnHost) += 1;
    lr.nonZeros = a.nonZeros();
    lr.secondsAssembly = secondsSince(t0);

    t0 = Clock::now();
    report(interrupter, {FitStage::Solve, k, levels, 0, 0.0, std::to_string(lr.nonZeros) + " non-zeros"}, &work);
    std::unique_ptr<LevelInterrupter> levelInterrupter;
    if (interrupter != nullptr) {
      levelInterrupter = std::make_unique<LevelInterrupter>(*interrupter, k, levels, work,
                                                            detail::levelSolverOptions(options, k >= levels).relativeTolerance);
    }
    lr.solve = detail::solveLevelSystem(device, a, b, options, k >= levels, lr.weights, levelInterrupter.get(),
                                        &levelBuffers, assembleOnDevice ? &assembled : nullptr);
    if (lr.solve.reason == StopReason::Cancelled) throw Cancelled("fit cancelled during the level " + std::to_string(k) + " solve");
    lr.secondsSolve = secondsSince(t0);
    return a;
  };

  std::vector<FieldLevel> fitted;
  // f_k as the levels are solved: one evaluator, each level appended once (right-hand sides, the offset
  // correction, E_0), handed on to extraction with the result.
  auto evaluator = std::make_shared<FieldEvaluator>(device, norm, -1.0, options.precision);
  // Overshoot check at the finest level (FitOptions::overshootCheck, docs/method.md "Overshoot between
  // sparse samples"): level M's bumps can add up to solid between sparse samples (a bulb over a sharp
  // ridge, a bridge across a narrow gap) where no constraint reaches: the off-surface points sit σ_M/10
  // off the surface and the sign anchors start 3 spacings away. Called with level M solved and appended to
  // `evaluator`: f_M is evaluated at p + s·D·ν (D = overshootSpacings median spacings, s each off-surface
  // side); where it is less than D/2 on its side and no other input point lies within D (so the surface is
  // about D away), the point joins level M with target s·D, the level is solved again and `fitted` and
  // `evaluator` get the new level M. Returns the level's matrix.
  auto overshootCheck = [&](detail::LevelConstraints& c, Eigen::VectorXd& b, CsrMatrix a, double sigma, int k,
                            LevelWork& lr) -> CsrMatrix {
    const auto t0 = Clock::now();
    if (spacing <= 0.0) {
      if (!inputIndex) inputIndex = std::make_unique<NeighborIndex>(u);
      spacing = detail::medianSpacing(estimatePointAreas(u, Points(-nu), WindingOptions().areaNeighbors, *inputIndex));
    }
    const double d = options.overshootSpacings * spacing;
    if (!(d > 0.0) || !std::isfinite(d)) return a;
    // The candidates in the Morton order of their points (u's order, §4.7): in the cloud's order
    // (fandisk_550k's is random) the evaluation took three times as long.
    std::vector<Eigen::Index> rows(static_cast<std::size_t>(u.rows()));
    std::iota(rows.begin(), rows.end(), Eigen::Index{0});
    detail::OvershootCandidates cand = detail::overshootCandidates(u, nu, rows, d, offSide);
    if (!inputIndex) inputIndex = std::make_unique<NeighborIndex>(u);
    double assembly = 0.0, solve = 0.0;
    for (int round = 0; round < options.overshootRounds; ++round) {
      // f_M at every candidate: `evaluator` holds level M as solved last.
      const std::vector<std::size_t> sites = detail::overshootSites(*evaluator, cand, *inputIndex, d);
      if (sites.empty()) break;
      // Their right-hand sides against f_{M−1}: level M leaves the evaluator until it is solved again.
      const Eigen::Index base = c.centres.rows(), extra = static_cast<Eigen::Index>(sites.size());
      Points at(extra, 3);
      for (Eigen::Index j = 0; j < extra; ++j) at.row(j) = cand.q.row(static_cast<Eigen::Index>(sites[static_cast<std::size_t>(j)]));
      evaluator->dropLastLevel();
      const Eigen::VectorXd g = evaluator->evaluateNormalized(at);
      c.centres.conservativeResize(base + extra, 3);
      c.targets.conservativeResize(base + extra);
      b.conservativeResize(base + extra);
      for (Eigen::Index j = 0; j < extra; ++j) {
        const double target = cand.toward[sites[static_cast<std::size_t>(j)]] * d;
        c.centres.row(base + j) = at.row(j);
        c.targets[base + j] = target;
        b[base + j] = target - g[j];
      }
      if (c.sources.size() == static_cast<std::size_t>(base)) c.sources.resize(static_cast<std::size_t>(base + extra), -1);
      assembly += lr.secondsAssembly;
      solve += lr.secondsSolve;
      a = solveLevel(c.centres, sigma, options.smoothing * k, b, k, lr);
      fitted.back() = FieldLevel{sigma, c.centres, std::move(lr.weights)};
      evaluator->appendLevel(fitted.back());
      lr.overshootSites += sites.size();
      lr.overshootRounds = round + 1;
    }
    lr.secondsAssembly += assembly;
    lr.secondsSolve += solve;
    lr.centres = static_cast<std::size_t>(c.centres.rows());
    lr.secondsOvershoot = secondsSince(t0);
    return a;
  };

  std::vector<Points> finestOffsetPoints(deltas.size());  // valid offset points of level M, per offset
  bool finestIsInput = false;              // the last level solved was level M (its points are the input)
  double e0Centres = 0.0;                  // max |f| at input points that are level-M centres
  std::vector<Eigen::Index> notCentres;    // input points that are not (merged away or dropped)
  for (int k = 1; k <= levels; ++k) {
    LevelWork lr;
    lr.level = k;
    const double sigma = sigma1 / std::pow(2.0, k - 1);
    lr.sigma = sigma / norm.scale;

    t = Clock::now();
    report(interrupter, {FitStage::Constraints, k, levels, 0, 0.0, ""}, &work);
    detail::LevelPoints level = k < levels ? detail::cellCentroids(u, nu, box, k) : detail::LevelPoints{u, nu};
    const detail::ConstraintOptions co =
        detail::levelConstraintOptions(options, deltas, sigma, k, levels, offSide, interrupter);
    detail::LevelConstraints c = detail::buildConstraints(level.positions, level.normals, co);
    lr.offsetMedial = c.offsetMedial;
    lr.offSurfaceMedial = c.offSurfaceMedial;
    if (k <= lastAnchorLevel) {
      detail::addLevelAnchors(c, sigma, spacing, deltas, anchorBox, k, k == lastAnchorLevel, u, nu, *winding, *inputIndex, lr,
                              norm.scale);
    }
    lr.surfacePoints = c.surface;
    lr.offsetCandidates = c.offsetCandidates;
    lr.offsetKept = c.offsetKept;
    lr.offSurfaceCandidates = c.offSurfaceCandidates;
    lr.offSurfaceKept = c.offSurfaceKept;
    lr.mergedCentres = c.merged;
    lr.centres = static_cast<std::size_t>(c.centres.rows());
    lr.secondsConstraints = secondsSince(t);

    // Right-hand side b = t − f_{k−1}(C) (§5), f_0 = −1.
    t = Clock::now();
    work.setLevel(k, c.centres.rows());
    report(interrupter, {FitStage::Residual, k, levels, 0, 0.0, ""}, &work);
    Eigen::VectorXd fPrev = Eigen::VectorXd::Constant(c.centres.rows(), -1.0);
    if (!fitted.empty()) fPrev = evaluator->evaluateNormalized(c.centres);
    Eigen::VectorXd b = c.targets - fPrev;
    lr.maxResidualBefore = (b.size() > 0 ? b.cwiseAbs().maxCoeff() : 0.0) / norm.scale;
    lr.secondsResidual = secondsSince(t);
    if (k >= 2 && options.fitTolerance > 0.0 && lr.maxResidualBefore * norm.scale <= options.fitTolerance) {
      rep.stoppedEarly = true;
      rep.levelReports.push_back(lr);
      break;
    }

    CsrMatrix a = solveLevel(c.centres, sigma, options.smoothing * k, b, k, lr);

    fitted.push_back(FieldLevel{sigma, c.centres, std::move(lr.weights)});
    evaluator->appendLevel(fitted.back());
    if (k == levels && options.overshootCheck && options.overshootRounds > 0 && offSide != 0 && u.rows() > 1) {
      a = overshootCheck(c, b, std::move(a), sigma, k, lr);
    }
    rep.levelReports.push_back(lr);
    if (k == levels) {
      // E_δ (§8.1) at the finest level's valid offset points: there b − A·w = t − f_M(c) exactly, so
      // the residual (in double on the host) gives the errors without evaluating the field again.
      const Eigen::VectorXd residual = b - a.multiply(fitted.back().weights);
      // E_0 likewise at the input points that are centres of this level (surface rows: t = 0).
      e0Centres = 0.0;
      for (const auto& [input, row] : c.surfaceCentres) e0Centres = std::max(e0Centres, std::abs(residual[row]));
      e0Centres /= norm.scale;
      notCentres = c.surfaceNotCentres;
      finestIsInput = true;
      rep.eDelta.assign(deltas.size(), 0.0);
      for (std::size_t j = 0; j < deltas.size(); ++j) {
        finestOffsetPoints[j].resize(static_cast<Eigen::Index>(c.offsetRows[j].size()), 3);
        Eigen::Index row = 0;
        for (const Eigen::Index r : c.offsetRows[j]) {
          rep.eDelta[j] = std::max(rep.eDelta[j], std::abs(residual[r]) / norm.scale);
          finestOffsetPoints[j].row(row++) = c.centres.row(r);
        }
      }
    }
    levelMatrix = std::move(a);
  }

  // Offset correction (docs/method.md, "Offset correction"): one extra level of small support fitted to
  // the difference between the true distance to the samples and δ on each fitted δ level.
  if (options.offsetCorrection && !deltas.empty() && !fitted.empty() && !rep.stoppedEarly) {
    t = Clock::now();
    report(interrupter, {FitStage::Correction, 0, levels, 0, 0.0, "offset levels against the distance to the samples"});
    OffsetCorrectionReport& cr = rep.correction;
    double minDelta = std::numeric_limits<double>::infinity();
    for (const double d : deltas) minDelta = std::min(minDelta, std::abs(d));
    const Points outwardNormals = -nu;
    const Eigen::VectorXd areas = winding ? winding->areas() : estimatePointAreas(u, outwardNormals);
    if (spacing <= 0.0) spacing = detail::medianSpacing(areas);
    if (!inputIndex) inputIndex = std::make_unique<NeighborIndex>(u);
    const double sigmaC = std::min(fitted.back().sigma, 0.5 * minDelta);
    cr.sigma = sigmaC / norm.scale;
    if (sigmaC >= 2.0 * spacing) {
      // Start from every companion p + δν, then Newton steps onto f = δ (each step at most |δ|/4).
      std::vector<Eigen::Index> source;
      for (Eigen::Index i = 0; i < u.rows(); ++i) {
        if (nu.row(i).squaredNorm() > 0.0) source.push_back(i);
      }
      const auto perOffset = static_cast<Eigen::Index>(source.size());
      Points x(perOffset * static_cast<Eigen::Index>(deltas.size()), 3);
      Eigen::VectorXd level(x.rows());
      for (std::size_t j = 0; j < deltas.size(); ++j) {
        for (Eigen::Index r = 0; r < perOffset; ++r) {
          const Eigen::Index i = source[static_cast<std::size_t>(r)];
          x.row(static_cast<Eigen::Index>(j) * perOffset + r) = u.row(i) + deltas[j] * nu.row(i);
          level[static_cast<Eigen::Index>(j) * perOffset + r] = deltas[j];
        }
      }
      auto sample = [&](const Points& xn, Eigen::VectorXd& fn, Points& g) {
        const Points world = ((xn / norm.scale).rowwise() + norm.centre.transpose()).eval();
        FieldSamples s = evaluator->evaluate(world, FieldDerivatives::Gradient);
        fn = s.values * norm.scale;
        g = std::move(s.gradients);
      };
      Eigen::VectorXd fn;
      Points g;
      for (int step = 0; step < 3; ++step) {
        sample(x, fn, g);
        for (Eigen::Index r = 0; r < x.rows(); ++r) {
          const double g2 = g.row(r).squaredNorm();
          if (!(g2 > 0.0)) continue;
          Eigen::RowVector3d dx = (fn[r] - level[r]) / g2 * g.row(r);
          const double len = dx.norm(), cap = 0.25 * std::abs(level[r]);
          if (len > cap) dx *= cap / len;
          x.row(r) -= dx;
        }
      }
      sample(x, fn, g);
      // Keep the points that reached their level on a slope (not the flat top of a ridge below δ),
      // thinned to about half the sample spacing.
      std::vector<Eigen::Index> keep;
      for (Eigen::Index r = 0; r < x.rows(); ++r) {
        if (std::abs(fn[r] - level[r]) <= 0.02 * std::abs(level[r]) && g.row(r).norm() >= 0.3) keep.push_back(r);
      }
      Points cx(static_cast<Eigen::Index>(keep.size()), 3);
      for (std::size_t r = 0; r < keep.size(); ++r) cx.row(static_cast<Eigen::Index>(r)) = x.row(keep[r]);
      std::vector<char> alive(keep.size(), 1);
      if (!keep.empty()) {
        const NeighborIndex ci(cx);
        const NeighborLists close = ci.radiusSearch(cx, 0.5 * spacing);
        for (std::size_t r = 0; r < keep.size(); ++r) {
          for (auto e = close.offsets[r]; e < close.offsets[r + 1]; ++e) {
            const auto j = static_cast<std::size_t>(close.indices[static_cast<std::size_t>(e)]);
            if (j < r && alive[j] != 0) {
              alive[r] = 0;
              break;
            }
          }
        }
      }
      std::vector<Eigen::Index> rows;
      for (std::size_t r = 0; r < keep.size(); ++r) {
        if (alive[r] != 0) rows.push_back(keep[r]);
      }
      Points centres(static_cast<Eigen::Index>(rows.size()), 3);
      for (std::size_t r = 0; r < rows.size(); ++r) centres.row(static_cast<Eigen::Index>(r)) = x.row(rows[r]);
      const Eigen::VectorXd dist = detail::diskSoupDistance(centres, u, nu, areas, *inputIndex);
      Eigen::VectorXd b(centres.rows());
      double sumBefore = 0.0, maxBefore = 0.0;
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const Eigen::Index i = rows[r];
        const double target = (level[i] > 0 ? 1.0 : -1.0) * dist[static_cast<Eigen::Index>(r)];
        b[static_cast<Eigen::Index>(r)] = target - fn[i];
        const double rel = std::abs(b[static_cast<Eigen::Index>(r)]) / std::abs(level[i]);
        sumBefore += rel;
        maxBefore = std::max(maxBefore, rel);
      }
      cr.points = static_cast<std::size_t>(centres.rows());
      cr.meanBefore = rows.empty() ? 0.0 : sumBefore / static_cast<double>(rows.size());
      cr.maxBefore = maxBefore;
      if (centres.rows() > 0) {
        LevelWork lw;
        lw.level = levels + 1;
        lw.sigma = sigmaC / norm.scale;
        lw.centres = cr.points;
        const CsrMatrix a = solveLevel(centres, sigmaC, 0.0, b, levels + 1, lw);
        cr.solve = lw.solve;
        cr.nonZeros = lw.nonZeros;
        fitted.push_back(FieldLevel{sigmaC, std::move(centres), std::move(lw.weights)});
        evaluator->appendLevel(fitted.back());
        cr.applied = true;
        finestIsInput = false;  // E_0 is evaluated again below, with the corrected field
      }
    }
    cr.seconds = secondsSince(t);
  }
  ImplicitField field(norm, -1.0, std::move(fitted), rep.offsets, bounds);
  if (rep.correction.applied) {
    // E_δ again at the finest level's valid offset points, now with the correction.
    for (std::size_t j = 0; j < deltas.size(); ++j) {
      if (finestOffsetPoints[j].rows() == 0) continue;
      const Eigen::VectorXd v = evaluator->evaluateNormalized(finestOffsetPoints[j]);
      rep.eDelta[j] = (v.array() - deltas[j]).abs().maxCoeff() / norm.scale;
    }
  }

  // E_0 (§8.1): max |f| at every input point. Those that are level-M centres have it from the final
  // residual; the others (merged away, dropped, or all of them after an early stop) are evaluated.
  report(interrupter, {FitStage::Errors, 0, levels, 0, 0.0, ""}, &work);
  Points rest;  // normalised, rows of u
  if (finestIsInput) {
    rest.resize(static_cast<Eigen::Index>(notCentres.size()), 3);
    for (std::size_t k = 0; k < notCentres.size(); ++k) rest.row(static_cast<Eigen::Index>(k)) = u.row(notCentres[k]);
    rep.e0 = e0Centres;
  } else {
    rest = u;
  }
  if (rest.rows() > 0) {
    const Eigen::VectorXd f0 = evaluator->evaluateNormalized(rest);
    rep.e0 = std::max(rep.e0, f0.cwiseAbs().maxCoeff() / norm.scale);
  }
  if (rep.eDelta.size() != deltas.size()) rep.eDelta.assign(deltas.size(), 0.0);  // stopped early
  rep.assembly = levelsOnDevice == 0 ? "host" : levelsOnHost == 0 ? "device" : "host and device";
  rep.secondsTotal = secondsSince(start);
  return FitResult{std::move(field), std::move(rep), std::move(evaluator)};
}

}  // namespace duplexfit
