// The distributed fit (docs/method.md, "Distributed fit"): the level loop of fit() over the blocks of a
// Morton-range partition. Coarse levels are gathered and solved identically on every rank; fine levels
// are solved by restricted additive Schwarz (each rank: its block plus a halo of g·σ_k, owned weights
// kept, gathered into the one field that every rank holds).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>

#include "duplexfit/distributed.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/wendland.hpp"
#include "duplexfit/winding.hpp"
#include "field/wendland_detail.hpp"
#include "fit/anchors.hpp"
#include "fit/constraints.hpp"
#include "fit/distributed_cg.hpp"
#include "fit/fit_detail.hpp"
#include "fit/hierarchy.hpp"
#include "fit/partition.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

void notify(Interrupter* interrupter, FitStage stage, int k, int levels, const std::string& message) {
  if (interrupter == nullptr) return;
  interrupter->fitEvent({stage, k, levels, 0, 0.0, message});
  if (interrupter->wasInterrupted(-1)) throw Cancelled(std::string("fit cancelled during ") + fitStageName(stage));
}

// The fit's normalisation and hierarchy box from the input's bounds, as fit() computes them.
struct Frame {
  Normalization norm;
  detail::HierarchyBox box;
  double side = 1.0;
};

Frame frameOf(const Eigen::AlignedBox3d& bounds) {
  Frame f;
  f.side = bounds.sizes().maxCoeff();
  f.norm.centre = bounds.center();
  f.norm.scale = 1.0 / f.side;
  // hierarchyBox only takes the coordinates' extremes: those of the normalised corners are the same
  // doubles as those of the normalised points.
  Points corners(2, 3);
  corners.row(0) = (f.norm.scale * (bounds.min() - f.norm.centre)).transpose();
  corners.row(1) = (f.norm.scale * (bounds.max() - f.norm.centre)).transpose();
  f.box = detail::hierarchyBox(corners);
  return f;
}

Points normalise(const Points& p, const Normalization& norm) {
  return (norm.scale * (p.rowwise() - norm.centre.transpose())).eval();
}

template <class T>
std::vector<T> rowsOf(const std::vector<T>& v, const std::vector<Eigen::Index>& rows) {
  std::vector<T> out;
  out.reserve(rows.size());
  for (const Eigen::Index r : rows) out.push_back(v[static_cast<std::size_t>(r)]);
  return out;
}

Points rowsOf(const Points& p, const std::vector<Eigen::Index>& rows) {
  Points out(static_cast<Eigen::Index>(rows.size()), 3);
  for (std::size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = p.row(rows[i]);
  return out;
}

}  // namespace

const char* distributedModeName(DistributedMode mode) noexcept {
  return mode == DistributedMode::Exact ? "exact" : "local";
}

DistributedPoints partitionPoints(Communicator& comm, const PointSet& myRows, std::int64_t firstRow,
                                  std::uint64_t fileRows, DistributedReport& report) {
  const auto t = Clock::now();
  // Global bounds by reduction.
  double lo[3] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
  double hi[3] = {-lo[0], -lo[1], -lo[2]};
  for (Eigen::Index i = 0; i < static_cast<Eigen::Index>(myRows.size()); ++i) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], myRows.positions()(i, a));
      hi[a] = std::max(hi[a], myRows.positions()(i, a));
    }
  }
  comm.allreduce(lo, 3, ReduceOp::Min);
  comm.allreduce(hi, 3, ReduceOp::Max);
  if (!(lo[0] <= hi[0])) throw InvalidArgument("distributed fit: no points on any rank");
  DistributedPoints out;
  out.bounds = Eigen::AlignedBox3d(Eigen::Vector3d(lo[0], lo[1], lo[2]), Eigen::Vector3d(hi[0], hi[1], hi[2]));
  const Frame frame = frameOf(out.bounds);
  const Points u = normalise(myRows.positions(), frame.norm);
  std::vector<std::uint64_t> keys(static_cast<std::size_t>(u.rows()));
  for (Eigen::Index i = 0; i < u.rows(); ++i) keys[static_cast<std::size_t>(i)] = detail::mortonKey63(u.row(i).transpose(), frame.box);
  out.splitters = detail::balancedSplitters(comm, keys);
  std::vector<std::int64_t> ids(static_cast<std::size_t>(u.rows()));
  for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = firstRow + static_cast<std::int64_t>(i);
  detail::OwnedRows owned =
      detail::redistribute(comm, myRows.positions(), myRows.normals(), ids, keys, out.splitters);

  // Every row owned once: the counts and Σ id agree with the file, and each rank's ids are increasing.
  std::int64_t check[3] = {static_cast<std::int64_t>(owned.ids.size()), 0, 0};
  for (std::size_t i = 0; i < owned.ids.size(); ++i) {
    check[1] += owned.ids[i];
    if (i > 0 && owned.ids[i] <= owned.ids[i - 1]) check[2] = 1;
  }
  comm.allreduce(check, 3, ReduceOp::Sum);
  const auto n = static_cast<std::int64_t>(fileRows);
  report.fileRows = fileRows;
  report.ownedRows = static_cast<std::uint64_t>(check[0]);
  report.ownedOnce = check[0] == n && check[1] == n * (n - 1) / 2 && check[2] == 0;
  report.ranks = comm.size();
  report.communicator = comm.name();

  PointSet set = PointSet::fromNormalized(std::move(owned.positions), std::move(owned.normals));
  set.mergeDuplicates();  // exact duplicates share a key, so a rank merges all of its own
  out.points = std::move(set);
  DistributedRankReport mine;
  mine.rank = comm.rank();
  mine.readRows = myRows.size();
  mine.points = out.points.size();
  mine.keyBegin = out.splitters[static_cast<std::size_t>(comm.rank())];
  mine.keyEnd = out.splitters[static_cast<std::size_t>(comm.rank()) + 1];
  mine.secondsPartition = secondsSince(t);
  report.rankReports = {mine};
  return out;
}

FitResult fitDistributed(const Device& device, Communicator& comm, const DistributedPoints& input,
                         const FitOptions& options, const DistributedOptions& dist, DistributedReport& drep,
                         Points* checkPoints, Interrupter* interrupter) {
  const auto start = Clock::now();
  detail::checkFitOptions(options);
  if (!(dist.halo > 0.0) || !std::isfinite(dist.halo)) throw InvalidArgument("distributed fit: --halo must be > 0");
  if (options.offsetCorrection) throw InvalidArgument("distributed fit: --offset-correction is not supported");
  device.requirePrecision(options.precision);
  const int ranks = comm.size(), me = comm.rank();
  const bool exact = dist.mode == DistributedMode::Exact;
  const PointSet& points = input.points;

  drep.mode = dist.mode;
  drep.halo = dist.halo;
  drep.coarsePoints = dist.coarsePoints;
  DistributedRankReport mine = drep.rankReports.empty() ? DistributedRankReport{} : drep.rankReports.front();
  mine.rank = me;
  std::uint64_t bytes = 0;

  FitReport rep;
  rep.device = device.description();
  rep.precision = precisionName(options.precision);
  rep.inputPoints = static_cast<std::size_t>(comm.allreduce(static_cast<std::int64_t>(points.size()), ReduceOp::Sum));
  rep.zeroNormals = static_cast<std::size_t>(comm.allreduce(static_cast<std::int64_t>(points.zeroNormals()), ReduceOp::Sum));
  if (rep.inputPoints < 4) throw InvalidArgument("distributed fit: " + std::to_string(rep.inputPoints) + " points, need at least 4");

  const Frame frame = frameOf(input.bounds);
  const Normalization& norm = frame.norm;
  const detail::HierarchyBox& box = frame.box;
  const Points u = normalise(points.positions(), norm);
  const Points nu = options.normalsInward ? points.normals() : Points(-points.normals());
  // Global ids of the owned points: the ranks' blocks in rank order (consistent on every rank, the file
  // order with one rank): every rank sorts what it holds by them, so a cell's sums run in one order.
  std::vector<std::int64_t> ids(static_cast<std::size_t>(u.rows()));
  {
    const std::vector<std::int64_t> counts = comm.allgather(std::vector<std::int64_t>{static_cast<std::int64_t>(u.rows())});
    std::int64_t first = 0;
    for (int r = 0; r < me; ++r) first += counts[static_cast<std::size_t>(r)];
    for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = first + static_cast<std::int64_t>(i);
  }

  std::vector<double> deltas;
  rep.offsets = detail::worldOffsets(options.offsets, options.offsetsRelative, frame.side);
  for (const double world : rep.offsets) deltas.push_back(world * norm.scale);
  const bool inward = std::any_of(deltas.begin(), deltas.end(), [](double d) { return d > 0; });
  const bool outward = std::any_of(deltas.begin(), deltas.end(), [](double d) { return d < 0; });
  const int offSide = inward && outward ? 0 : inward ? -1 : outward ? 1 : 2;
  rep.offSurfaceSide = offSide == 0    ? OffSurfaceSide::None
                       : offSide == -1 ? OffSurfaceSide::Outside
                       : offSide == 1  ? OffSurfaceSide::Inside
                                       : OffSurfaceSide::Both;
  double maxOffset = 0.0;
  for (const double d : deltas) maxOffset = std::max(maxOffset, std::abs(d));

  // Hierarchy: σ_0 from the blocks' octrees, reduced (exact with one rank).
  auto t = Clock::now();
  notify(interrupter, FitStage::Hierarchy, 0, 0, "building the octrees");
  const double sigma1 = options.alpha * box.diagonal;
  double octree[2] = {0.0, 0.0};
  {
    std::size_t leaves = 0;
    detail::adaptiveOctreeSums(u, box, octree[0], leaves);
    octree[1] = static_cast<double>(leaves);
  }
  comm.allreduce(octree, 2, ReduceOp::Sum);
  const double sigma0 = octree[1] == 0.0 ? 0.75 * box.diagonal : 0.75 * octree[0] / octree[1];
  drep.sigma0Approximate = ranks > 1;
  const int levels = options.levels > 0 ? options.levels : detail::levelCount(sigma1, sigma0);
  rep.sigma0 = sigma0 / norm.scale;
  rep.sigma1 = sigma1 / norm.scale;
  rep.levels = levels;
  rep.secondsHierarchy = secondsSince(t);

  // Sign anchors: with one rank the winding number of the whole cloud (as fit()); with several, that of a
  // proxy cloud every rank holds (the gathered centroids of a fine depth), on the gathered levels only.
  const int lastAnchorLevel = options.signAnchors ? levels - std::max(0, options.anchorSkipFinest) : 0;
  Points cloud, cloudNormals;  // the anchors' cloud (normalised, inward normals)
  std::unique_ptr<WindingNumber> winding;
  std::unique_ptr<NeighborIndex> cloudIndex;
  double spacing = 0.0;
  int proxyDepth = 0;
  {
    // The proxy for the self-check and the anchors: the finest depth below M with few enough cells.
    for (int d = std::max(1, levels - 1); d >= 1; --d) {
      const auto cells = comm.allreduce(static_cast<std::int64_t>(detail::cellSums(u, nu, box, d).size()), ReduceOp::Sum);
      if (static_cast<std::size_t>(cells) <= dist.windingPoints || d == 1) {
        proxyDepth = d;
        break;
      }
    }
  }
  detail::LevelPoints proxy;
  if (ranks > 1 || checkPoints != nullptr) proxy = detail::gatheredCentroids(comm, u, nu, box, proxyDepth);
  if (checkPoints != nullptr) {
    *checkPoints = ((proxy.positions / norm.scale).rowwise() + norm.centre.transpose()).eval();
  }
  if (lastAnchorLevel >= 1) {
    t = Clock::now();
    notify(interrupter, FitStage::Hierarchy, 0, 0, "winding number");
    if (ranks == 1) {
      cloud = u;
      cloudNormals = nu;
    } else {
      cloud = proxy.positions;
      cloudNormals = proxy.normals;
      drep.windingProxyPoints = static_cast<std::size_t>(cloud.rows());
    }
    const Points outwardNormals = -cloudNormals;
    winding = std::make_unique<WindingNumber>(cloud, outwardNormals);
    cloudIndex = std::make_unique<NeighborIndex>(cloud);
    spacing = detail::medianSpacing(winding->areas());
    rep.secondsWinding = secondsSince(t);
  }
  Eigen::AlignedBox3d anchorBox(box.min, box.max);
  anchorBox.min().array() -= 0.1 + maxOffset;
  anchorBox.max().array() += 0.1 + maxOffset;

  std::vector<FieldLevel> fitted;
  auto evaluator = std::make_shared<FieldEvaluator>(device, norm, -1.0, options.precision);
  std::vector<Points> finestOffsetPoints(deltas.size());  // owned valid offset points of level M
  for (int k = 1; k <= levels; ++k) {
    const auto levelStart = Clock::now();
    const std::uint64_t bytesBefore = bytes;
    LevelReport lr;
    DistributedLevelReport dl;
    lr.level = dl.level = k;
    const double sigma = sigma1 / std::pow(2.0, k - 1);
    lr.sigma = sigma / norm.scale;

    t = Clock::now();
    notify(interrupter, FitStage::Constraints, k, levels, "");
    // Gathered when the level has few points (all ranks together; cells counted per rank, an upper bound).
    const std::int64_t levelPointsAll =
        k < levels ? comm.allreduce(static_cast<std::int64_t>(detail::cellSums(u, nu, box, k).size()), ReduceOp::Sum)
                   : static_cast<std::int64_t>(rep.inputPoints);
    const bool gathered = static_cast<std::size_t>(levelPointsAll) <= dist.coarsePoints;
    dl.gathered = gathered;

    detail::LevelPoints level;
    std::vector<char> ownedPoint;     // per level point: this rank owns it
    std::vector<char> inSystem;       // per level point: within g·σ_k of an owned one
    if (gathered) {
      level = k < levels ? detail::gatheredCentroids(comm, u, nu, box, k) : detail::LevelPoints{};
      if (k == levels) {
        // The whole cloud in the ranks' id order (the file order with one rank).
        const std::vector<double> pos = comm.allgather(std::vector<double>(u.data(), u.data() + u.size()));
        const std::vector<double> nrm = comm.allgather(std::vector<double>(nu.data(), nu.data() + nu.size()));
        // Rebuilt block by block (each rank's rows, in rank order).
        const std::vector<std::int64_t> rows = comm.allgather(std::vector<std::int64_t>{static_cast<std::int64_t>(u.rows())});
        std::int64_t total = 0;
        for (const auto r : rows) total += r;
        level.positions.resize(total, 3);
        level.normals.resize(total, 3);
        std::size_t at = 0;
        Eigen::Index row = 0;
        for (const auto r : rows) {
          const Eigen::Map<const Points> p(pos.data() + at, r, 3), q(nrm.data() + at, r, 3);
          level.positions.middleRows(row, r) = p;
          level.normals.middleRows(row, r) = q;
          at += static_cast<std::size_t>(3 * r);
          row += r;
        }
        bytes += static_cast<std::uint64_t>(2 * pos.size() * sizeof(double));
      }
      ownedPoint.assign(static_cast<std::size_t>(level.positions.rows()), 1);
      inSystem = ownedPoint;
    } else {
      // Input points of the other ranks within the data radius (cells of level k must be complete there).
      // Exact mode keeps only the owned centres, whose constraints (validity tests within 2|δ| of a level
      // point, merges, cells whole) need a margin, not a halo system: 2σ_k + 3 max|δ| + 2 cell diagonals.
      const double cellDiag = k < levels ? box.diagonal / std::pow(2.0, k) : 0.0;
      const double radius = exact ? 2.0 * sigma + 3.0 * maxOffset + 2.0 * cellDiag
                                  : (dist.halo + 1.0) * sigma + 2.0 * maxOffset + cellDiag;
      detail::OwnedRows halo = detail::exchangeHalo(comm, u, nu, ids, box, radius);
      dl.haloPoints = halo.ids.size();
      bytes += static_cast<std::uint64_t>(halo.ids.size()) * 56;
      // Owned and halo points in id order.
      const auto n = static_cast<Eigen::Index>(u.rows() + halo.positions.rows());
      std::vector<std::pair<std::int64_t, Eigen::Index>> order;
      order.reserve(static_cast<std::size_t>(n));
      for (Eigen::Index i = 0; i < u.rows(); ++i) order.emplace_back(ids[static_cast<std::size_t>(i)], i);
      for (Eigen::Index i = 0; i < halo.positions.rows(); ++i) order.emplace_back(halo.ids[static_cast<std::size_t>(i)], u.rows() + i);
      std::sort(order.begin(), order.end());
      Points lp(n, 3), ln(n, 3);
      std::vector<char> ownedRow(static_cast<std::size_t>(n));
      for (Eigen::Index r = 0; r < n; ++r) {
        const Eigen::Index i = order[static_cast<std::size_t>(r)].second;
        const bool own = i < u.rows();
        if (own) {
          lp.row(r) = u.row(i);
          ln.row(r) = nu.row(i);
        } else {
          lp.row(r) = halo.positions.row(i - u.rows());
          ln.row(r) = halo.normals.row(i - u.rows());
        }
        ownedRow[static_cast<std::size_t>(r)] = own ? 1 : 0;
      }
      if (k < levels) {
        level = detail::cellCentroids(lp, ln, box, k);
        // A cell's point belongs to the rank whose Morton range holds the centroid.
        ownedPoint.resize(static_cast<std::size_t>(level.positions.rows()));
        for (Eigen::Index i = 0; i < level.positions.rows(); ++i) {
          ownedPoint[static_cast<std::size_t>(i)] =
              detail::ownerOfKey(input.splitters, detail::mortonKey63(level.positions.row(i).transpose(), box)) == me ? 1 : 0;
        }
      } else {
        level = detail::LevelPoints{lp, ln};
        ownedPoint = ownedRow;
      }
      // Level points within g·σ_k of an owned one are in the rank's system.
      std::vector<Eigen::Index> ownedRows;
      for (std::size_t i = 0; i < ownedPoint.size(); ++i) {
        if (ownedPoint[i] != 0) ownedRows.push_back(static_cast<Eigen::Index>(i));
      }
      inSystem.assign(ownedPoint.size(), 0);
      if (exact) {
        inSystem = ownedPoint;  // the rank's rows of the global system: its owned centres
      } else if (!ownedRows.empty()) {
        const NeighborIndex ownedIndex(rowsOf(level.positions, ownedRows));
        const NeighborLists nearest = ownedIndex.knnSearch(level.positions, 1);
        for (std::size_t i = 0; i < inSystem.size(); ++i) {
          if (nearest.offsets[i + 1] == nearest.offsets[i]) continue;
          const auto j = static_cast<Eigen::Index>(nearest.indices[static_cast<std::size_t>(nearest.offsets[i])]);
          const double d = (level.positions.row(static_cast<Eigen::Index>(i)) - level.positions.row(ownedRows[static_cast<std::size_t>(j)])).norm();
          inSystem[i] = d <= dist.halo * sigma ? 1 : 0;
        }
      }
    }
    dl.levelPoints = static_cast<std::size_t>(level.positions.rows());

    detail::ConstraintOptions co;
    co.offsets = deltas;
    co.offSurfaceDistance = sigma / 10.0;
    co.offSurfaceSide = offSide;
    co.validityTolerance = options.validityTolerance;
    co.mergeDistance = options.mergeDistance * sigma;
    co.dropZeroNormalPoints = options.dropZeroNormalPoints;
    co.tangentSideTest = options.sideTest;
    co.medial = options.medialConstraints;
    detail::LevelConstraints c = detail::buildConstraints(level.positions, level.normals, co);
    const Eigen::Index mergedCentres = c.centres.rows();
    // The rank's system: the centres of the level points in it; anchors (with one rank, or gathered levels).
    if (!gathered) {
      std::vector<Eigen::Index> keep;
      for (Eigen::Index r = 0; r < c.centres.rows(); ++r) {
        if (inSystem[static_cast<std::size_t>(c.sources[static_cast<std::size_t>(r)])] != 0) keep.push_back(r);
      }
      if (static_cast<Eigen::Index>(keep.size()) != c.centres.rows()) {
        std::vector<Eigen::Index> newRow(static_cast<std::size_t>(c.centres.rows()), -1);
        for (std::size_t i = 0; i < keep.size(); ++i) newRow[static_cast<std::size_t>(keep[i])] = static_cast<Eigen::Index>(i);
        c.centres = rowsOf(c.centres, keep);
        Eigen::VectorXd targets(static_cast<Eigen::Index>(keep.size()));
        for (std::size_t i = 0; i < keep.size(); ++i) targets[static_cast<Eigen::Index>(i)] = c.targets[keep[i]];
        c.targets = std::move(targets);
        c.sources = rowsOf(c.sources, keep);
        for (auto& rows : c.offsetRows) {
          std::vector<Eigen::Index> kept;
          for (const Eigen::Index r : rows) {
            if (newRow[static_cast<std::size_t>(r)] >= 0) kept.push_back(newRow[static_cast<std::size_t>(r)]);
          }
          rows = std::move(kept);
        }
        c.candidateIndex.reset();
      }
    }
    const Eigen::Index systemCentres = c.centres.rows();
    if (k <= lastAnchorLevel && (gathered || ranks == 1)) {
      detail::addLevelAnchors(c, sigma, spacing, deltas, anchorBox, k, cloud, cloudNormals, *winding, *cloudIndex, lr,
                              norm.scale);
    }
    lr.offsetMedial = c.offsetMedial;
    lr.offSurfaceMedial = c.offSurfaceMedial;
    lr.surfacePoints = c.surface;
    lr.offsetCandidates = c.offsetCandidates;
    lr.offsetKept = c.offsetKept;
    lr.offSurfaceCandidates = c.offSurfaceCandidates;
    lr.offSurfaceKept = c.offSurfaceKept;
    lr.mergedCentres = c.merged;
    lr.secondsConstraints = secondsSince(t);

    // b = t − f_{k−1}(C).
    t = Clock::now();
    notify(interrupter, FitStage::Residual, k, levels, "");
    Eigen::VectorXd fPrev = Eigen::VectorXd::Constant(c.centres.rows(), -1.0);
    if (!fitted.empty() && c.centres.rows() > 0) fPrev = evaluator->evaluateNormalized(c.centres);
    const Eigen::VectorXd b = c.targets - fPrev;
    lr.maxResidualBefore = comm.allreduce((b.size() > 0 ? b.cwiseAbs().maxCoeff() : 0.0) / norm.scale, ReduceOp::Max);
    lr.secondsResidual = secondsSince(t);
    if (k >= 2 && options.fitTolerance > 0.0 && lr.maxResidualBefore * norm.scale <= options.fitTolerance) {
      rep.stoppedEarly = true;
      rep.levelReports.push_back(lr);
      break;
    }

    // Assemble and solve the rank's system (the level's whole system when gathered); exact mode: the
    // rank's rows of the level's global system, solved by distributed PCG.
    t = Clock::now();
    notify(interrupter, FitStage::Assembly, k, levels, std::to_string(c.centres.rows()) + " centres");
    const double lambda = options.smoothing * k;
    SolverOptions so = options.solver;
    if (so.absoluteTolerance == 0.0) so.absoluteTolerance = options.levelTolerance;
    if (k < levels && options.coarseTolerance > 0.0) so.relativeTolerance = options.coarseTolerance;
    Eigen::VectorXd weights = Eigen::VectorXd::Zero(b.size());
    std::size_t nonZeros = 0;
    if (exact && !gathered) {
      const detail::DistributedSystem system = detail::distributedSystem(comm, c.centres, sigma, lambda, box);
      bytes += system.setupBytes;
      nonZeros = system.rows.nonZeros();
      dl.ghosts = system.ghosts;
      lr.secondsAssembly = secondsSince(t);
      t = Clock::now();
      notify(interrupter, FitStage::Solve, k, levels, std::to_string(nonZeros) + " non-zeros (this rank's rows)");
      const int blockSize = options.preconditioner == PreconditionerKind::BlockJacobi ? options.blockSize : 1;
      const detail::DistributedSolve solved =
          detail::solveDistributedCg(comm, system, b, weights, so, options.precision, blockSize);
      lr.solve = solved.stats;
      bytes += solved.bytes;
    } else {
      const bool reuseIndex = c.candidateIndex && c.centres.rows() == mergedCentres;
      const CsrMatrix a = reuseIndex ? detail::assembleWendland(c.centres, sigma, lambda, *c.candidateIndex, c.candidateRow)
                                     : assembleWendland(c.centres, sigma, lambda);
      nonZeros = a.nonZeros();
      lr.secondsAssembly = secondsSince(t);
      t = Clock::now();
      notify(interrupter, FitStage::Solve, k, levels, std::to_string(a.nonZeros()) + " non-zeros");
      if (b.size() > 0) {
        const DeviceCsr m = DeviceCsr::upload(device, a, options.precision);
        const DeviceVector db = DeviceVector::upload(device, b, options.precision);
        DeviceVector x(device, static_cast<std::size_t>(b.size()), options.precision);
        std::unique_ptr<Preconditioner> pre;
        if (options.preconditioner == PreconditionerKind::BlockJacobi) {
          pre = std::make_unique<BlockJacobiPreconditioner>(device, a, options.precision, options.blockSize);
        } else {
          pre = std::make_unique<JacobiPreconditioner>(m);
        }
        lr.solve = solveCg(m, db, x, so, pre.get(), nullptr);
        weights = x.download();
      } else {
        lr.solve.converged = true;
        lr.solve.reason = StopReason::Converged;
      }
    }
    lr.secondsSolve = secondsSince(t);
    dl.secondsSolve = lr.secondsSolve;
    dl.unknowns = static_cast<std::size_t>(c.centres.rows());
    dl.nonZeros = nonZeros;
    dl.iterations = lr.solve.iterations;

    // Keep the owned centres (every centre of a gathered level) and gather the level.
    std::vector<Eigen::Index> ownedCentres;
    for (Eigen::Index r = 0; r < c.centres.rows(); ++r) {
      const Eigen::Index s = r < systemCentres ? c.sources[static_cast<std::size_t>(r)] : -1;
      const bool own = gathered || (s >= 0 ? ownedPoint[static_cast<std::size_t>(s)] != 0
                                           : detail::ownerOfKey(input.splitters, detail::mortonKey63(c.centres.row(r).transpose(), box)) == me);
      if (own) ownedCentres.push_back(r);
    }
    dl.ownedCentres = ownedCentres.size();
    FieldLevel fl;
    fl.sigma = sigma;
    if (gathered) {
      fl.centres = c.centres;
      fl.weights = weights;
    } else {
      const Points oc = rowsOf(c.centres, ownedCentres);
      std::vector<double> packed;
      packed.reserve(ownedCentres.size() * 4);
      for (std::size_t i = 0; i < ownedCentres.size(); ++i) {
        for (int a3 = 0; a3 < 3; ++a3) packed.push_back(oc(static_cast<Eigen::Index>(i), a3));
        packed.push_back(weights[ownedCentres[i]]);
      }
      const std::vector<double> all = comm.allgather(packed);
      bytes += static_cast<std::uint64_t>(all.size() * sizeof(double));
      const auto n = static_cast<Eigen::Index>(all.size() / 4);
      fl.centres.resize(n, 3);
      fl.weights.resize(n);
      for (Eigen::Index i = 0; i < n; ++i) {
        for (int a3 = 0; a3 < 3; ++a3) fl.centres(i, a3) = all[static_cast<std::size_t>(4 * i + a3)];
        fl.weights[i] = all[static_cast<std::size_t>(4 * i + 3)];
      }
    }
    // The level's report: counts over the ranks (gathered levels: one rank's, the same everywhere).
    lr.centres = static_cast<std::size_t>(fl.centres.rows());
    lr.nonZeros = static_cast<std::size_t>(comm.allreduce(static_cast<std::int64_t>(gathered ? (me == 0 ? nonZeros : 0) : nonZeros), ReduceOp::Sum));
    lr.solve.iterations = static_cast<int>(comm.allreduce(static_cast<std::int64_t>(lr.solve.iterations), ReduceOp::Max));
    lr.solve.converged = comm.allreduce(static_cast<std::int64_t>(lr.solve.converged ? 0 : 1), ReduceOp::Sum) == 0;
    lr.solve.relativeResidual = comm.allreduce(lr.solve.relativeResidual, ReduceOp::Max);
    lr.solve.maxResidual = comm.allreduce(lr.solve.maxResidual, ReduceOp::Max);
    if (k == levels) {
      for (std::size_t j = 0; j < deltas.size(); ++j) {
        std::vector<Eigen::Index> rows;
        for (const Eigen::Index r : c.offsetRows[j]) {
          const Eigen::Index s = c.sources[static_cast<std::size_t>(r)];
          if (gathered ? me == 0 : ownedPoint[static_cast<std::size_t>(s)] != 0) rows.push_back(r);
        }
        finestOffsetPoints[j] = rowsOf(c.centres, rows);
      }
    }
    fitted.push_back(std::move(fl));
    evaluator->appendLevel(fitted.back());
    rep.levelReports.push_back(lr);
    dl.seconds = secondsSince(levelStart);
    dl.bytes = bytes - bytesBefore;
    mine.levels.push_back(dl);
  }

  // E_0 at the owned input points and E_δ at the owned finest offset points, from the final field.
  notify(interrupter, FitStage::Errors, 0, levels, "");
  double e0 = 0.0;
  if (u.rows() > 0) e0 = evaluator->evaluateNormalized(u).cwiseAbs().maxCoeff() / norm.scale;
  rep.e0 = comm.allreduce(e0, ReduceOp::Max);
  rep.eDelta.assign(deltas.size(), 0.0);
  if (!rep.stoppedEarly) {
    for (std::size_t j = 0; j < deltas.size(); ++j) {
      double e = 0.0;
      if (finestOffsetPoints[j].rows() > 0) {
        e = (evaluator->evaluateNormalized(finestOffsetPoints[j]).array() - deltas[j]).abs().maxCoeff() / norm.scale;
      }
      rep.eDelta[j] = comm.allreduce(e, ReduceOp::Max);
    }
  }
  ImplicitField field(norm, -1.0, std::move(fitted), rep.offsets, input.bounds);

  // Every rank's report on every rank (fixed-size records, levels flattened).
  mine.secondsFit = secondsSince(start);
  mine.bytesReceived = bytes;
  struct Flat {
    double v[11];
  };
  std::vector<Flat> flat;
  flat.push_back({{static_cast<double>(mine.rank), static_cast<double>(mine.readRows), static_cast<double>(mine.points),
                   static_cast<double>(mine.keyBegin), static_cast<double>(mine.keyEnd), mine.secondsPartition,
                   mine.secondsFit, static_cast<double>(mine.bytesReceived), 0.0, 0.0, 0.0}});
  for (const DistributedLevelReport& l : mine.levels) {
    flat.push_back({{static_cast<double>(l.level) + (l.gathered ? 0.5 : 0.0), static_cast<double>(l.levelPoints),
                     static_cast<double>(l.haloPoints), static_cast<double>(l.unknowns), static_cast<double>(l.ownedCentres),
                     static_cast<double>(l.nonZeros), static_cast<double>(l.iterations), l.seconds,
                     static_cast<double>(l.ghosts), static_cast<double>(l.bytes), l.secondsSolve}});
  }
  std::vector<std::size_t> counts;
  const std::vector<Flat> all = comm.allgather(flat, &counts);
  drep.rankReports.clear();
  std::size_t at = 0;
  for (const std::size_t n : counts) {
    DistributedRankReport r;
    const Flat& h = all[at];
    r.rank = static_cast<int>(h.v[0]);
    r.readRows = static_cast<std::size_t>(h.v[1]);
    r.points = static_cast<std::size_t>(h.v[2]);
    r.keyBegin = static_cast<std::uint64_t>(h.v[3]);
    r.keyEnd = static_cast<std::uint64_t>(h.v[4]);
    r.secondsPartition = h.v[5];
    r.secondsFit = h.v[6];
    r.bytesReceived = static_cast<std::uint64_t>(h.v[7]);
    for (std::size_t i = 1; i < n; ++i) {
      const Flat& f = all[at + i];
      DistributedLevelReport l;
      l.level = static_cast<int>(f.v[0]);
      l.gathered = f.v[0] - l.level > 0.25;
      l.levelPoints = static_cast<std::size_t>(f.v[1]);
      l.haloPoints = static_cast<std::size_t>(f.v[2]);
      l.unknowns = static_cast<std::size_t>(f.v[3]);
      l.ownedCentres = static_cast<std::size_t>(f.v[4]);
      l.nonZeros = static_cast<std::size_t>(f.v[5]);
      l.iterations = static_cast<int>(f.v[6]);
      l.seconds = f.v[7];
      l.ghosts = static_cast<std::size_t>(f.v[8]);
      l.bytes = static_cast<std::uint64_t>(f.v[9]);
      l.secondsSolve = f.v[10];
      r.levels.push_back(l);
    }
    drep.rankReports.push_back(r);
    at += n;
  }
  rep.secondsTotal = secondsSince(start);
  return FitResult{std::move(field), std::move(rep), std::move(evaluator)};
}

}  // namespace duplexfit
