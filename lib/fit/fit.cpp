// The duplex-fit pipeline (algorithm.md appendix): normalise to the unit box, build the hierarchy, and for
// each level generate the constraints, assemble Φ_k + λ_k I, take b = t − f_{k−1}(C) from the field so far
// (evaluated on the device), solve by PCG on the device, and append the level. Then measure E_0 and E_δ.
#include "duplexfit/fit.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>

#include "duplexfit/error.hpp"
#include "duplexfit/wendland.hpp"
#include "fit/constraints.hpp"
#include "fit/hierarchy.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

void report(const FitProgressCallback& progress, FitProgress event) {
  if (progress && !progress(event)) throw Cancelled("fit cancelled during " + event.stage);
}

void checkOptions(const FitOptions& o) {
  auto bad = [](const std::string& what) { throw InvalidArgument("fit options: " + what); };
  if (!(o.validityTolerance >= 0.0 && o.validityTolerance < 1.0)) bad("validityTolerance must be in [0, 1)");
  if (o.levels < 0 || o.levels > 24) bad("levels must be between 0 (automatic) and 24");
  if (!(o.alpha > 0.0) || !std::isfinite(o.alpha)) bad("alpha must be positive");
  if (!(o.smoothing >= 0.0) || !std::isfinite(o.smoothing)) bad("smoothing must be >= 0");
  if (!(o.fitTolerance >= 0.0) || !std::isfinite(o.fitTolerance)) bad("fitTolerance must be >= 0");
  if (!(o.mergeDistance >= 0.0 && o.mergeDistance < 0.5)) bad("mergeDistance must be in [0, 0.5)");
  if (!(o.levelTolerance >= 0.0) || !std::isfinite(o.levelTolerance)) bad("levelTolerance must be >= 0");
  if (o.blockSize < 1 || o.blockSize > 256) bad("blockSize must be in [1, 256]");
  for (double d : o.offsets) {
    if (!std::isfinite(d)) bad("offsets must be finite");
  }
}

}  // namespace

FitResult fit(const Device& device, const PointSet& points, const FitOptions& options,
              const FitProgressCallback& progress) {
  const auto start = Clock::now();
  checkOptions(options);
  checkFittable(points, "input cloud");
  device.requirePrecision(options.precision);

  FitReport rep;
  rep.device = device.description();
  rep.precision = precisionName(options.precision);
  rep.inputPoints = points.size();
  rep.zeroNormals = points.zeroNormals();

  // Normalise: centre the bounding box and scale its largest side to 1 (float-safe coordinates).
  const Eigen::AlignedBox3d bounds = points.bounds();
  const double side = bounds.sizes().maxCoeff();
  Normalization norm;
  norm.centre = bounds.center();
  norm.scale = 1.0 / side;
  const Points u = (norm.scale * (points.positions().rowwise() - norm.centre.transpose())).eval();
  const Points nu = options.normalsInward ? points.normals() : Points(-points.normals());

  // Offsets in input units (report) and normalised units (fit).
  std::vector<double> deltas;
  rep.offsets = detail::worldOffsets(options.offsets, options.offsetsRelative, side);
  for (const double world : rep.offsets) deltas.push_back(world * norm.scale);
  const bool inward = std::any_of(deltas.begin(), deltas.end(), [](double d) { return d > 0; });
  const bool outward = std::any_of(deltas.begin(), deltas.end(), [](double d) { return d < 0; });
  // Off-surface points go on the side without offsets (§3.2); none when offsets cover both sides.
  const int offSide = inward && outward ? 0 : inward ? -1 : outward ? 1 : 2;
  rep.offSurfaceSide = offSide == 0    ? "none (offsets on both sides)"
                       : offSide == -1 ? "outside"
                       : offSide == 1  ? "inside"
                                       : "both sides (no offsets)";

  // Hierarchy (§4).
  auto t = Clock::now();
  report(progress, {"hierarchy", 0, 0, 0, 0.0, "building the octree"});
  const detail::HierarchyBox box = detail::hierarchyBox(u);
  const double sigma1 = options.alpha * box.diagonal;
  const double sigma0 = detail::adaptiveSigma0(u, box);
  const int levels = options.levels > 0 ? options.levels : detail::levelCount(sigma1, sigma0);
  rep.sigma0 = sigma0 / norm.scale;
  rep.sigma1 = sigma1 / norm.scale;
  rep.levels = levels;
  rep.secondsHierarchy = since(t);

  std::vector<FieldLevel> fitted;
  bool finestIsInput = false;              // the last level solved was level M (its points are the input)
  double e0Centres = 0.0;                  // max |f| at input points that are level-M centres
  std::vector<Eigen::Index> notCentres;    // input points that are not (merged away or dropped)
  for (int k = 1; k <= levels; ++k) {
    LevelReport lr;
    lr.level = k;
    const double sigma = sigma1 / std::pow(2.0, k - 1);
    lr.sigma = sigma / norm.scale;

    t = Clock::now();
    report(progress, {"constraints", k, levels, 0, 0.0, ""});
    detail::LevelPoints level = k < levels ? detail::cellCentroids(u, nu, box, k) : detail::LevelPoints{u, nu};
    detail::ConstraintOptions co;
    co.offsets = deltas;
    co.offSurfaceDistance = sigma / 10.0;
    co.offSurfaceSide = offSide;
    co.validityTolerance = options.validityTolerance;
    co.mergeDistance = options.mergeDistance * sigma;
    co.dropZeroNormalPoints = options.dropZeroNormalPoints;
    co.tangentSideTest = options.sideTest;
    detail::LevelConstraints c = detail::buildConstraints(level.positions, level.normals, co);
    lr.surfacePoints = c.surface;
    lr.offsetCandidates = c.offsetCandidates;
    lr.offsetKept = c.offsetKept;
    lr.offSurfaceCandidates = c.offSurfaceCandidates;
    lr.offSurfaceKept = c.offSurfaceKept;
    lr.mergedCentres = c.merged;
    lr.centres = static_cast<std::size_t>(c.centres.rows());
    lr.secondsConstraints = since(t);

    // Right-hand side b = t − f_{k−1}(C) (§5), f_0 = −1.
    t = Clock::now();
    report(progress, {"residual", k, levels, 0, 0.0, ""});
    Eigen::VectorXd fPrev = Eigen::VectorXd::Constant(c.centres.rows(), -1.0);
    if (!fitted.empty()) {
      const ImplicitField partial(norm, -1.0, fitted, rep.offsets, bounds);
      fPrev = FieldEvaluator(device, partial, options.precision).evaluateNormalized(c.centres);
    }
    const Eigen::VectorXd b = c.targets - fPrev;
    lr.maxResidualBefore = (b.size() > 0 ? b.cwiseAbs().maxCoeff() : 0.0) / norm.scale;
    lr.secondsResidual = since(t);
    if (k >= 2 && options.fitTolerance > 0.0 && lr.maxResidualBefore * norm.scale <= options.fitTolerance) {
      rep.stoppedEarly = true;
      rep.levelReports.push_back(lr);
      break;
    }

    t = Clock::now();
    report(progress, {"assembly", k, levels, 0, 0.0, std::to_string(lr.centres) + " centres"});
    const CsrMatrix a = assembleWendland(c.centres, sigma, options.smoothing * k);
    lr.nonZeros = a.nonZeros();
    lr.secondsAssembly = since(t);

    t = Clock::now();
    report(progress, {"solve", k, levels, 0, 0.0, std::to_string(lr.nonZeros) + " non-zeros"});
    const DeviceCsr m = DeviceCsr::upload(device, a, options.precision);
    const DeviceVector db = DeviceVector::upload(device, b, options.precision);
    DeviceVector x(device, static_cast<std::size_t>(b.size()), options.precision);
    SolverOptions so = options.solver;
    if (so.absoluteTolerance == 0.0) so.absoluteTolerance = options.levelTolerance;
    so.progress = [&](int it, double res) {
      if (options.solver.progress && !options.solver.progress(it, res)) return false;
      return !progress || progress({"solve", k, levels, it, res, ""});
    };
    std::unique_ptr<Preconditioner> pre;
    if (options.preconditioner == PreconditionerKind::BlockJacobi) {
      pre = std::make_unique<BlockJacobiPreconditioner>(device, a, options.precision, options.blockSize);
    } else {
      pre = std::make_unique<JacobiPreconditioner>(m);
    }
    lr.solve = solveCg(m, db, x, so, pre.get());
    if (lr.solve.reason == StopReason::Cancelled) throw Cancelled("fit cancelled during the level " + std::to_string(k) + " solve");
    lr.secondsSolve = since(t);

    fitted.push_back(FieldLevel{sigma, c.centres, x.download()});
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
        for (const Eigen::Index r : c.offsetRows[j]) {
          rep.eDelta[j] = std::max(rep.eDelta[j], std::abs(residual[r]) / norm.scale);
        }
      }
    }
  }
  ImplicitField field(norm, -1.0, std::move(fitted), rep.offsets, bounds);

  // E_0 (§8.1): max |f| at every input point. Those that are level-M centres have it from the final
  // residual; the others (merged away, dropped, or all of them after an early stop) are evaluated.
  report(progress, {"errors", 0, levels, 0, 0.0, ""});
  Points rest;
  if (finestIsInput) {
    rest.resize(static_cast<Eigen::Index>(notCentres.size()), 3);
    for (std::size_t k = 0; k < notCentres.size(); ++k) rest.row(static_cast<Eigen::Index>(k)) = points.positions().row(notCentres[k]);
    rep.e0 = e0Centres;
  } else {
    rest = points.positions();
  }
  if (rest.rows() > 0) {
    const Eigen::VectorXd f0 = FieldEvaluator(device, field, options.precision).evaluate(rest).values;
    rep.e0 = std::max(rep.e0, f0.cwiseAbs().maxCoeff());
  }
  if (rep.eDelta.size() != deltas.size()) rep.eDelta.assign(deltas.size(), 0.0);  // stopped early
  rep.secondsTotal = since(start);
  return FitResult{std::move(field), std::move(rep)};
}

}  // namespace duplexfit
