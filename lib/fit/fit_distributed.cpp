// The distributed fit (docs/method.md, "Distributed fit"): the level loop of fit() over the blocks of a
// Morton-range partition. Coarse levels are gathered and solved identically on every rank; fine levels
// are solved by restricted additive Schwarz (each rank: its block plus a halo of g·σ_k, owned weights
// kept, gathered into the one field that every rank holds).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <sstream>

#include "duplexfit/distributed.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/resources.hpp"
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

constexpr int kMaxBlocks = 1 << 16;

/// Reports the event and polls with the fit's percent (−1: unknown), as fit() does.
void notify(Interrupter* interrupter, FitStage stage, int k, int levels, const std::string& message, int percent = -1) {
  if (interrupter == nullptr) return;
  interrupter->fitEvent({stage, k, levels, 0, 0.0, message});
  if (interrupter->wasInterrupted(percent)) throw Cancelled(std::string("fit cancelled during ") + fitStageName(stage));
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
                                  std::uint64_t fileRows, DistributedReport& report, int blocks) {
  const auto t = Clock::now();
  const int ranks = comm.size();
  const int nBlocks = blocks > 0 ? blocks : ranks;
  if (blocks < 0 || nBlocks < ranks || nBlocks > kMaxBlocks) {
    throw InvalidArgument("distributed fit: " + std::to_string(blocks) + " blocks for " + std::to_string(ranks) +
                          " ranks: give between one block per rank and " + std::to_string(kMaxBlocks) + " blocks");
  }
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
  // The blocks' Morton ranges; rank r holds the consecutive blocks [⌊rB/P⌋, ⌊(r+1)B/P⌋) (with one block per
  // rank, the blocks are the ranks' ranges).
  out.blockSplitters = detail::balancedSplitters(comm, keys, 18, nBlocks);
  out.splitters.resize(static_cast<std::size_t>(ranks) + 1);
  for (int r = 0; r <= ranks; ++r) {
    out.splitters[static_cast<std::size_t>(r)] =
        out.blockSplitters[static_cast<std::size_t>(detail::firstBlockOfRank(r, ranks, nBlocks))];
  }
  out.firstBlock = detail::firstBlockOfRank(comm.rank(), ranks, nBlocks);
  const int localBlocks = detail::firstBlockOfRank(comm.rank() + 1, ranks, nBlocks) - out.firstBlock;
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
  report.ranks = ranks;
  report.blocks = nBlocks;
  report.communicator = comm.name();

  PointSet set = PointSet::fromNormalized(std::move(owned.positions), std::move(owned.normals));
  set.mergeDuplicates();  // exact duplicates share a key, so a rank merges all of its own
  // In Morton order (detail::mortonOrder, ties in file order), so block by block (a block is a key range):
  // the order of the ranks' points if each block were a rank, so that B blocks in one process reproduce B
  // ranks, and with one rank the serial fit's own order (it sorts its points so).
  std::vector<Eigen::Index> count(static_cast<std::size_t>(localBlocks) + 1, 0);
  {
    const Points un = normalise(set.positions(), frame.norm);
    const std::vector<Eigen::Index> order = detail::mortonOrder(un, frame.box);
    for (Eigen::Index i = 0; i < un.rows(); ++i) {
      const int b = detail::ownerOfKey(out.blockSplitters, detail::mortonKey63(un.row(i).transpose(), frame.box)) - out.firstBlock;
      if (b < 0 || b >= localBlocks) throw InvalidArgument("distributed fit: a point outside its rank's blocks (internal error)");
      ++count[static_cast<std::size_t>(b) + 1];
    }
    set = PointSet::fromNormalized(set.positions()(order, Eigen::all), set.normals()(order, Eigen::all));
  }
  for (int b = 0; b < localBlocks; ++b) count[static_cast<std::size_t>(b) + 1] += count[static_cast<std::size_t>(b)];
  out.blockRows = count;
  out.points = std::move(set);
  report.rankReports.clear();
  for (int b = 0; b < localBlocks; ++b) {
    DistributedRankReport mine;
    mine.rank = comm.rank();
    mine.block = out.firstBlock + b;
    mine.readRows = b == 0 ? myRows.size() : 0;
    mine.points = static_cast<std::size_t>(out.blockRows[static_cast<std::size_t>(b) + 1] - out.blockRows[static_cast<std::size_t>(b)]);
    mine.keyBegin = out.blockSplitters[static_cast<std::size_t>(mine.block)];
    mine.keyEnd = out.blockSplitters[static_cast<std::size_t>(mine.block) + 1];
    mine.secondsPartition = secondsSince(t);
    report.rankReports.push_back(mine);
  }
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

  // This rank's blocks: [firstBlock, firstBlock + localBlocks), rows blockRows of the points.
  const int localBlocks = input.blockRows.size() >= 2 ? static_cast<int>(input.blockRows.size()) - 1 : 1;
  const std::vector<Eigen::Index> blockRows =
      input.blockRows.size() >= 2 ? input.blockRows : std::vector<Eigen::Index>{0, static_cast<Eigen::Index>(points.size())};
  const std::vector<std::uint64_t>& blockSplitters = input.blockSplitters.empty() ? input.splitters : input.blockSplitters;
  if (blockRows.back() != static_cast<Eigen::Index>(points.size()) ||
      blockSplitters.size() < static_cast<std::size_t>(input.firstBlock + localBlocks) + 1) {
    throw InvalidArgument("distributed fit: the points' blocks do not match the partition (internal error)");
  }
  const int parts = static_cast<int>(comm.allreduce(static_cast<std::int64_t>(localBlocks), ReduceOp::Sum));
  if (exact && parts != ranks) {
    throw InvalidArgument("distributed fit: exact mode solves one block per rank (" + std::to_string(parts) + " blocks on " +
                          std::to_string(ranks) + " ranks); use --distributed local with --blocks");
  }

  drep.mode = dist.mode;
  drep.halo = dist.halo;
  drep.coarsePoints = dist.coarsePoints;
  drep.blocks = parts;
  std::vector<DistributedRankReport> mine(static_cast<std::size_t>(localBlocks));
  for (int j = 0; j < localBlocks; ++j) {
    if (static_cast<std::size_t>(j) < drep.rankReports.size()) mine[static_cast<std::size_t>(j)] = drep.rankReports[static_cast<std::size_t>(j)];
    mine[static_cast<std::size_t>(j)].rank = me;
    mine[static_cast<std::size_t>(j)].block = input.firstBlock + j;
  }
  std::uint64_t bytes = 0;

  FitReport rep;
  rep.device = device.description();
  rep.deviceTuning = device.tuning().describe();
  rep.precision = precisionName(options.precision);
  rep.preconditioner = detail::preconditionerName(options) + " (gathered levels); " +
                       (options.preconditioner == PreconditionerKind::Jacobi ? std::string("jacobi")
                                                                              : BlockJacobiPreconditioner::describe(options.blockSize)) +
                       " on each rank's rows (distributed levels)";
  rep.inputPoints = static_cast<std::size_t>(comm.allreduce(static_cast<std::int64_t>(points.size()), ReduceOp::Sum));
  rep.zeroNormals = static_cast<std::size_t>(comm.allreduce(static_cast<std::int64_t>(points.zeroNormals()), ReduceOp::Sum));
  if (rep.inputPoints < 4) throw InvalidArgument("distributed fit: " + std::to_string(rep.inputPoints) + " points, need at least 4");

  const Frame frame = frameOf(input.bounds);
  const Normalization& norm = frame.norm;
  const detail::HierarchyBox& box = frame.box;
  const Points u = normalise(points.positions(), norm);
  const Points nu = options.normalsInward ? points.normals() : Points(-points.normals());
  // f(positions, normals) for each of this rank's blocks: a rank of B blocks computes what B ranks would.
  // Runs f on each local block in turn, polling the interrupter before each (a block's octree or cell
  // sums take seconds at millions of points).
  const auto forEachBlock = [&](const auto& f) {
    if (localBlocks == 1) {
      f(0, u, nu);
      return;
    }
    for (int j = 0; j < localBlocks; ++j) {
      if (interrupter != nullptr && interrupter->wasInterrupted(-1)) throw Cancelled("fit cancelled during the blocks' hierarchy");
      const Eigen::Index b0 = blockRows[static_cast<std::size_t>(j)], n = blockRows[static_cast<std::size_t>(j) + 1] - b0;
      f(j, Points(u.middleRows(b0, n)), Points(nu.middleRows(b0, n)));
    }
  };
  // Σ over the blocks of their cell counts at depth d (cells that straddle blocks counted once per block).
  const auto blockCellCount = [&](int d) {
    std::int64_t cells = 0;
    forEachBlock([&](int, const Points& pb, const Points& nb) { cells += static_cast<std::int64_t>(detail::cellSums(pb, nb, box, d).size()); });
    return comm.allreduce(cells, ReduceOp::Sum);
  };
  // Global ids of the owned points: the ranks' blocks in rank order (consistent on every rank, the file
  // order with one rank): every rank sorts what it holds by them, so a cell's sums run in one order.
  std::vector<std::int64_t> ids(static_cast<std::size_t>(u.rows()));
  {
    const std::vector<std::int64_t> counts = comm.allgather(std::vector<std::int64_t>{static_cast<std::int64_t>(u.rows())});
    std::int64_t first = 0;
    for (int r = 0; r < me; ++r) first += counts[static_cast<std::size_t>(r)];
    for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = first + static_cast<std::int64_t>(i);
  }

  rep.smoothing = options.smoothing;
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
  forEachBlock([&](int, const Points& pb, const Points&) {
    double diagonals = 0.0;
    std::size_t leaves = 0;
    detail::adaptiveOctreeSums(pb, box, diagonals, leaves);
    octree[0] += diagonals;
    octree[1] += static_cast<double>(leaves);
  });
  comm.allreduce(octree, 2, ReduceOp::Sum);
  const double sigma0 = octree[1] == 0.0 ? 0.75 * box.diagonal : 0.75 * octree[0] / octree[1];
  drep.sigma0Approximate = parts > 1;
  const int levels = options.levels > 0 ? options.levels : detail::levelCount(sigma1, sigma0);
  rep.sigma0 = sigma0 / norm.scale;
  rep.sigma1 = sigma1 / norm.scale;
  rep.levels = levels;
  rep.secondsHierarchy = secondsSince(t);
  // The fit's percent for the progress line and its ETA: every level's work from its cell count (known at
  // the level's start, the later ones extrapolated), each level's blocks in turn (detail::FitWork).
  detail::FitWork work(levels, static_cast<Eigen::Index>(rep.inputPoints), deltas.size());

  // Sign anchors: with one block the winding number of the whole cloud (as fit()); with several, that of a
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
      const std::int64_t cells = blockCellCount(d);
      if (static_cast<std::size_t>(cells) <= dist.windingPoints || d == 1) {
        proxyDepth = d;
        break;
      }
    }
  }
  detail::LevelPoints proxy;
  if (parts > 1 || checkPoints != nullptr) proxy = detail::gatheredCentroids(comm, u, nu, box, proxyDepth);
  if (checkPoints != nullptr) {
    *checkPoints = ((proxy.positions / norm.scale).rowwise() + norm.centre.transpose()).eval();
  }
  if (lastAnchorLevel >= 1) {
    t = Clock::now();
    notify(interrupter, FitStage::Hierarchy, 0, 0, "winding number");
    if (parts == 1) {
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
  // The local block of each owned point.
  std::vector<int> blockOfRow(static_cast<std::size_t>(u.rows()), 0);
  for (int j = 0; j < localBlocks; ++j) {
    for (Eigen::Index i = blockRows[static_cast<std::size_t>(j)]; i < blockRows[static_cast<std::size_t>(j) + 1]; ++i) {
      blockOfRow[static_cast<std::size_t>(i)] = j;
    }
  }
  // The overshoot check at the finest level (docs/method.md, "Overshoot between sparse samples"), as fit()
  // runs it: after level M is solved and gathered, each rank tests the candidates of its own points against
  // the whole field; the sites of all ranks join level M, which is solved again (every unit, with the sites
  // it owns and, in local mode, those within its halo). With one rank and one block this is fit()'s check.
  Points overshootAt;                 // every rank's sites so far, in rank order (normalised)
  Eigen::VectorXd overshootTargets;   // s·D
  // This rank's candidates, made once (level M's data are the same in every pass) and marked as they join.
  std::unique_ptr<detail::OvershootCandidates> overshootCandidates;
  int overshootRound = 0;
  double overshootSeconds = 0.0;
  double overshootSpacing = -1.0;     // D's spacing, once found (the same in every round)
  for (int k = 1; k <= levels; ++k) {
    const auto levelStart = Clock::now();
    if (k == levels) {
      for (Points& p : finestOffsetPoints) p.resize(0, 3);  // level M again after an overshoot round
    }
    const std::uint64_t bytesBefore = bytes;
    LevelReport lr;
    lr.level = k;
    const double sigma = sigma1 / std::pow(2.0, k - 1);
    lr.sigma = sigma / norm.scale;
    std::vector<DistributedLevelReport> dls(static_cast<std::size_t>(localBlocks));
    for (DistributedLevelReport& dl : dls) dl.level = k;

    t = Clock::now();
    // Gathered when the level has few points (all blocks together; cells counted per block, an upper bound).
    const std::int64_t levelPointsAll = k < levels ? blockCellCount(k) : static_cast<std::int64_t>(rep.inputPoints);
    work.setLevel(k, static_cast<Eigen::Index>(levelPointsAll) * static_cast<Eigen::Index>(2 + deltas.size()));
    notify(interrupter, FitStage::Constraints, k, levels, "", work.percent(k, 0.0));
    const bool gathered = static_cast<std::size_t>(levelPointsAll) <= dist.coarsePoints;
    for (DistributedLevelReport& dl : dls) dl.gathered = gathered;

    // The rank's data: its points and (not gathered) the other ranks' points within the data radius, in
    // id order. Exact mode keeps only the owned centres, whose constraints (validity tests within 2|δ| of
    // a level point, merges, cells whole) need a margin, not a halo system: 2σ_k + 3 max|δ| + 2 cell
    // diagonals. Local mode: (g + 1)σ_k + 2 max|δ| + one cell diagonal. Both + 3σ_k for the crease-plane
    // test (where levelConstraintOptions asks for it), which looks up to 2σ_k (its largest disc) further from a companion than the validity test and
    // classifies the points it finds by their 8 nearest neighbours (about σ_k at the finest level).
    const detail::ConstraintOptions co = detail::levelConstraintOptions(options, deltas, sigma, k, levels, offSide, interrupter);
    const double cellDiag = k < levels ? box.diagonal / std::pow(2.0, k) : 0.0;
    const double crease = co.creaseTest ? co.creaseRadiusCap + sigma : 0.0;
    const double radius = exact ? 2.0 * sigma + 3.0 * maxOffset + 2.0 * cellDiag + crease
                                : (dist.halo + 1.0) * sigma + 2.0 * maxOffset + cellDiag + crease;
    Points lp, ln;
    std::vector<int> rowBlock;  // per row of lp: its local block, −1 for another rank's point
    Eigen::Index firstOwnRow = 0;  // gathered level M: this rank's first row in lp
    if (gathered) {
      if (k == levels) {
        // The whole cloud in the ranks' id order (the file order with one rank).
        const std::vector<double> pos = comm.allgather(std::vector<double>(u.data(), u.data() + u.size()));
        const std::vector<double> nrm = comm.allgather(std::vector<double>(nu.data(), nu.data() + nu.size()));
        // Rebuilt block by block (each rank's rows, in rank order).
        const std::vector<std::int64_t> rows = comm.allgather(std::vector<std::int64_t>{static_cast<std::int64_t>(u.rows())});
        std::int64_t total = 0;
        for (const auto r : rows) total += r;
        lp.resize(total, 3);
        ln.resize(total, 3);
        std::size_t at = 0;
        Eigen::Index row = 0;
        for (int r = 0; r < me; ++r) firstOwnRow += rows[static_cast<std::size_t>(r)];
        for (const auto r : rows) {
          const Eigen::Map<const Points> p(pos.data() + at, r, 3), q(nrm.data() + at, r, 3);
          lp.middleRows(row, r) = p;
          ln.middleRows(row, r) = q;
          at += static_cast<std::size_t>(3 * r);
          row += r;
        }
        bytes += static_cast<std::uint64_t>(2 * pos.size() * sizeof(double));
      }
    } else {
      detail::OwnedRows halo = detail::exchangeHalo(comm, u, nu, ids, box, radius);
      bytes += static_cast<std::uint64_t>(halo.ids.size()) * 56;
      const auto n = static_cast<Eigen::Index>(u.rows() + halo.positions.rows());
      std::vector<std::pair<std::int64_t, Eigen::Index>> order;
      order.reserve(static_cast<std::size_t>(n));
      for (Eigen::Index i = 0; i < u.rows(); ++i) order.emplace_back(ids[static_cast<std::size_t>(i)], i);
      for (Eigen::Index i = 0; i < halo.positions.rows(); ++i) order.emplace_back(halo.ids[static_cast<std::size_t>(i)], u.rows() + i);
      std::sort(order.begin(), order.end());
      lp.resize(n, 3);
      ln.resize(n, 3);
      rowBlock.resize(static_cast<std::size_t>(n));
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
        rowBlock[static_cast<std::size_t>(r)] = own ? blockOfRow[static_cast<std::size_t>(i)] : -1;
      }
    }

    // The level's solve units: the whole level when gathered, else each of the rank's blocks in turn (its
    // points, the data within the radius of them, its system; only one block's system exists at a time).
    // Their owned centres and weights are packed (x, y, z, w) for the gather.
    const int units = gathered ? 1 : localBlocks;
    std::vector<double> packed;
    double maxResidual = 0.0;
    for (int j = 0; j < units; ++j) {
      DistributedLevelReport& dl = dls[static_cast<std::size_t>(j)];
      const int block = input.firstBlock + j;
      const std::string unitName = units > 1 ? "block " + std::to_string(block + 1) + " of " + std::to_string(parts) + ": " : "";
      const auto unitStart = Clock::now();
      auto tu = unitStart;
      // The percent at a stage of this unit.
      const auto at = [&](FitStage stage) { return work.percent(k, detail::unitWithin(j, units, detail::stageStart(stage))); };
      if (units > 1) notify(interrupter, FitStage::Constraints, k, levels, unitName + "constraints", at(FitStage::Constraints));
      detail::LevelPoints level;
      std::vector<char> ownedPoint;  // per level point: this unit owns it
      if (gathered) {
        level = k < levels ? detail::gatheredCentroids(comm, u, nu, box, k) : detail::LevelPoints{lp, ln};
        ownedPoint.assign(static_cast<std::size_t>(level.positions.rows()), 1);
      } else {
        // The block's data: with one block per rank all the rank's rows, else those near the block's own.
        std::vector<char> core(rowBlock.size());
        for (std::size_t r = 0; r < rowBlock.size(); ++r) core[r] = rowBlock[r] == j ? 1 : 0;
        Points bp, bn;
        std::vector<char> ownedRow;
        if (localBlocks == 1) {
          bp = lp;
          bn = ln;
          ownedRow = core;
        } else {
          const std::vector<Eigen::Index> rows = detail::rowsNear(lp, core, box, radius);
          bp = rowsOf(lp, rows);
          bn = rowsOf(ln, rows);
          ownedRow = rowsOf(core, rows);
        }
        std::size_t own = 0;
        for (const char c : ownedRow) own += c != 0 ? 1 : 0;
        dl.haloPoints = ownedRow.size() - own;
        if (k < levels) {
          level = detail::cellCentroids(bp, bn, box, k);
          // A cell's point belongs to the block whose Morton range holds the centroid.
          ownedPoint.resize(static_cast<std::size_t>(level.positions.rows()));
          for (Eigen::Index i = 0; i < level.positions.rows(); ++i) {
            ownedPoint[static_cast<std::size_t>(i)] =
                detail::ownerOfKey(blockSplitters, detail::mortonKey63(level.positions.row(i).transpose(), box)) == block ? 1 : 0;
          }
        } else {
          level = detail::LevelPoints{std::move(bp), std::move(bn)};
          ownedPoint = std::move(ownedRow);
        }
      }
      dl.levelPoints = static_cast<std::size_t>(level.positions.rows());

      detail::LevelConstraints c = detail::buildConstraints(level.positions, level.normals, co);
      // The unit's system: its owned centres (those of its level points) and, in local mode, every centre
      // within g·σ_k of an owned one, by position: an offset centre lies |δ| from its source, so on a thin
      // part it neighbours centres whose sources are across the part (the data radius, (g+1)σ_k + 2 max|δ|,
      // holds their sources). Exact mode: the owned centres only (the rank's rows of the global system).
      // Anchors: one block, or gathered levels.
      // The unit's owned centres' index (local mode), also asked for the overshoot sites near them below.
      std::unique_ptr<NeighborIndex> ownedIndex;
      if (!gathered) {
        std::vector<char> inSystem(static_cast<std::size_t>(c.centres.rows()), 0);
        std::vector<Eigen::Index> ownedRows;
        for (Eigen::Index r = 0; r < c.centres.rows(); ++r) {
          if (ownedPoint[static_cast<std::size_t>(c.sources[static_cast<std::size_t>(r)])] != 0) {
            inSystem[static_cast<std::size_t>(r)] = 1;
            ownedRows.push_back(r);
          }
        }
        if (!exact && !ownedRows.empty()) {
          // Only the centres not owned are asked, and only within the halo: a search for the nearest owned
          // centre of one far beyond the block (the data radius reaches (g + 1)σ_k + 2 max|δ|) was most of
          // a 20M-point --blocks fit's level 11 (perf: 95% of the samples in that tree search).
          std::vector<Eigen::Index> others;
          for (Eigen::Index r = 0; r < c.centres.rows(); ++r) {
            if (inSystem[static_cast<std::size_t>(r)] == 0) others.push_back(r);
          }
          ownedIndex = std::make_unique<NeighborIndex>(rowsOf(c.centres, ownedRows));
          const NeighborLists nearest = ownedIndex->nearestWithin(rowsOf(c.centres, others), dist.halo * sigma);
          for (std::size_t o = 0; o < others.size(); ++o) {
            if (nearest.offsets[o + 1] == nearest.offsets[o]) continue;
            const auto i = static_cast<std::size_t>(others[o]);
            const auto q = static_cast<Eigen::Index>(nearest.indices[static_cast<std::size_t>(nearest.offsets[o])]);
            const double d = (c.centres.row(static_cast<Eigen::Index>(i)) - c.centres.row(ownedRows[static_cast<std::size_t>(q)])).norm();
            inSystem[i] = d <= dist.halo * sigma ? 1 : 0;
          }
        }
        std::vector<Eigen::Index> keep;
        for (Eigen::Index r = 0; r < c.centres.rows(); ++r) {
          if (inSystem[static_cast<std::size_t>(r)] != 0) keep.push_back(r);
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
        }
      }
      const Eigen::Index systemCentres = c.centres.rows();
      if (k <= lastAnchorLevel && (gathered || parts == 1)) {
        detail::addLevelAnchors(c, sigma, spacing, deltas, anchorBox, k, k == lastAnchorLevel, cloud, cloudNormals, *winding,
                                *cloudIndex, lr, norm.scale);
      }
      if (k == levels && overshootAt.rows() > 0) {
        // The overshoot sites this unit's system holds: all of them on a gathered level, else those it owns
        // (by key) and, in local mode, those within g·σ of one of its owned centres.
        std::vector<Eigen::Index> take;
        if (gathered) {
          for (Eigen::Index i = 0; i < overshootAt.rows(); ++i) take.push_back(i);
        } else {
          std::vector<Eigen::Index> others;
          for (Eigen::Index i = 0; i < overshootAt.rows(); ++i) {
            if (detail::ownerOfKey(blockSplitters, detail::mortonKey63(overshootAt.row(i).transpose(), box)) == block) {
              take.push_back(i);
            } else if (!exact) {
              others.push_back(i);
            }
          }
          if (!others.empty() && ownedIndex) {  // local mode with owned centres: the index of the system's test
            const NeighborLists near = ownedIndex->nearestWithin(rowsOf(overshootAt, others), dist.halo * sigma);
            for (std::size_t o = 0; o < others.size(); ++o) {
              if (near.offsets[o + 1] > near.offsets[o]) take.push_back(others[o]);
            }
            std::sort(take.begin(), take.end());
          }
        }
        const Eigen::Index base = c.centres.rows(), extra = static_cast<Eigen::Index>(take.size());
        c.centres.conservativeResize(base + extra, 3);
        c.targets.conservativeResize(base + extra);
        for (Eigen::Index x = 0; x < extra; ++x) {
          c.centres.row(base + x) = overshootAt.row(take[static_cast<std::size_t>(x)]);
          c.targets[base + x] = overshootTargets[take[static_cast<std::size_t>(x)]];
        }
        if (c.sources.size() == static_cast<std::size_t>(base)) c.sources.resize(static_cast<std::size_t>(base + extra), -1);
      }
      lr.offsetMedial = c.offsetMedial;
      lr.offSurfaceMedial = c.offSurfaceMedial;
      lr.surfacePoints += c.surface;
      lr.offsetCandidates = c.offsetCandidates;
      lr.offsetKept = c.offsetKept;
      lr.offSurfaceCandidates += c.offSurfaceCandidates;
      lr.offSurfaceKept += c.offSurfaceKept;
      lr.mergedCentres += c.merged;
      lr.secondsConstraints += secondsSince(tu);

      // b = t − f_{k−1}(C).
      tu = Clock::now();
      notify(interrupter, FitStage::Residual, k, levels, unitName, at(FitStage::Residual));
      Eigen::VectorXd fPrev = Eigen::VectorXd::Constant(c.centres.rows(), -1.0);
      if (!fitted.empty() && c.centres.rows() > 0) fPrev = evaluator->evaluateNormalized(c.centres);
      const Eigen::VectorXd b = c.targets - fPrev;
      maxResidual = std::max(maxResidual, b.size() > 0 ? b.cwiseAbs().maxCoeff() : 0.0);
      lr.secondsResidual += secondsSince(tu);

      // Assemble and solve the unit's system (the level's whole system when gathered); exact mode: the
      // rank's rows of the level's global system, solved by distributed PCG.
      tu = Clock::now();
      notify(interrupter, FitStage::Assembly, k, levels, unitName + std::to_string(c.centres.rows()) + " centres",
             at(FitStage::Assembly));
      const double lambda = options.smoothing * k;
      Eigen::VectorXd weights = Eigen::VectorXd::Zero(b.size());
      SolveStats solve;
      std::size_t nonZeros = 0;
      if (exact && !gathered) {
        const detail::DistributedSystem system = detail::distributedSystem(comm, c.centres, sigma, lambda, box);
        bytes += system.setupBytes;
        nonZeros = system.rows.nonZeros();
        dl.ghosts = system.ghosts;
        lr.secondsAssembly += secondsSince(tu);
        tu = Clock::now();
        notify(interrupter, FitStage::Solve, k, levels, std::to_string(nonZeros) + " non-zeros (this rank's rows)",
               at(FitStage::Solve));
        // FSAI is not distributed: the distributed levels keep block Jacobi on each rank's rows with it.
        const int blockSize = options.preconditioner == PreconditionerKind::Jacobi ? 1 : options.blockSize;
        const detail::DistributedSolve solved = detail::solveDistributedCg(
            comm, system, b, weights, detail::levelSolverOptions(options, k >= levels), options.precision, blockSize);
        solve = solved.stats;
        bytes += solved.bytes;
      } else {
        // The memory budget, per unit: with blocks, one block's system is all that is held at a time.
        const detail::NonZeroCheck budget = [&](std::size_t z) {
          std::ostringstream what;
          what.precision(3);
          what << unitName << "level " << k << " of " << levels << " (" << c.centres.rows() << " centres, about "
               << static_cast<double>(z) << " non-zeros)";
          requireMemory(options.limits, "fit", estimateLevelBytes(static_cast<std::size_t>(c.centres.rows()), z, options),
                        what.str(), gathered ? "raise --coarse-points less, or fit a sparser cloud" : "use more --blocks");
        };
        const CsrMatrix a = detail::assembleWendland(c.centres, sigma, lambda, budget, interrupter);
        nonZeros = a.nonZeros();
        lr.secondsAssembly += secondsSince(tu);
        tu = Clock::now();
        notify(interrupter, FitStage::Solve, k, levels, unitName + std::to_string(a.nonZeros()) + " non-zeros",
               at(FitStage::Solve));
        // The solve reports its iterations with the level, polls with the fit's percent and can be stopped.
        std::unique_ptr<detail::LevelInterrupter> monitor;
        if (interrupter != nullptr) {
          monitor = std::make_unique<detail::LevelInterrupter>(
              *interrupter, k, levels, work, detail::levelSolverOptions(options, k >= levels).relativeTolerance, j, units);
        }
        solve = detail::solveLevelSystem(device, a, b, options, k >= levels, weights, monitor.get());
        if (solve.reason == StopReason::Cancelled) {
          throw Cancelled("fit cancelled during the level " + std::to_string(k) + " solve" +
                          (units > 1 ? " of block " + std::to_string(block + 1) : std::string()));
        }
      }
      const double solveSeconds = secondsSince(tu);
      lr.secondsSolve += solveSeconds;
      dl.secondsSolve = solveSeconds;
      dl.unknowns = static_cast<std::size_t>(c.centres.rows());
      dl.nonZeros = nonZeros;
      dl.iterations = solve.iterations;
      if (j == 0) {
        lr.solve = solve;
      } else {
        // The blocks' solves as one: the most iterations, the worst residuals, converged if all did.
        lr.solve.iterations = std::max(lr.solve.iterations, solve.iterations);
        if (!solve.converged && lr.solve.converged) {
          lr.solve.converged = false;
          lr.solve.reason = solve.reason;
        }
        lr.solve.relativeResidual = std::max(lr.solve.relativeResidual, solve.relativeResidual);
        lr.solve.recurrenceResidual = std::max(lr.solve.recurrenceResidual, solve.recurrenceResidual);
        lr.solve.maxResidual = std::max(lr.solve.maxResidual, solve.maxResidual);
        lr.solve.seconds += solve.seconds;
      }

      // Keep the owned centres (every centre of a gathered level).
      std::vector<Eigen::Index> ownedCentres;
      for (Eigen::Index r = 0; r < c.centres.rows(); ++r) {
        const Eigen::Index src = r < systemCentres ? c.sources[static_cast<std::size_t>(r)] : -1;
        const bool own = gathered || (src >= 0 ? ownedPoint[static_cast<std::size_t>(src)] != 0
                                               : detail::ownerOfKey(blockSplitters, detail::mortonKey63(c.centres.row(r).transpose(), box)) == block);
        if (own) ownedCentres.push_back(r);
      }
      dl.ownedCentres = ownedCentres.size();
      packed.reserve(packed.size() + ownedCentres.size() * 4);
      for (const Eigen::Index r : ownedCentres) {
        for (int a3 = 0; a3 < 3; ++a3) packed.push_back(c.centres(r, a3));
        packed.push_back(weights[r]);
      }
      if (k == levels) {
        for (std::size_t q = 0; q < deltas.size(); ++q) {
          std::vector<Eigen::Index> rows;
          for (const Eigen::Index r : c.offsetRows[q]) {
            const Eigen::Index src = c.sources[static_cast<std::size_t>(r)];
            if (gathered ? me == 0 : ownedPoint[static_cast<std::size_t>(src)] != 0) rows.push_back(r);
          }
          const Points add = rowsOf(c.centres, rows);
          Points& all = finestOffsetPoints[q];
          Points grown(all.rows() + add.rows(), 3);
          grown << all, add;
          all = std::move(grown);
        }
      }
      dl.seconds = secondsSince(unitStart);
      mine[static_cast<std::size_t>(j)].peakBytes = std::max(mine[static_cast<std::size_t>(j)].peakBytes, peakResidentBytes());
    }

    // The level's residual before its solve, over all blocks: with fitTolerance, a level already within it
    // is dropped (fit() stops before solving it; here the blocks have been solved, the result is the same).
    lr.maxResidualBefore = comm.allreduce(maxResidual / norm.scale, ReduceOp::Max);
    if (k >= 2 && options.fitTolerance > 0.0 && lr.maxResidualBefore * norm.scale <= options.fitTolerance) {
      rep.stoppedEarly = true;
      rep.levelReports.push_back(lr);
      break;
    }

    // The level: every unit's owned centres, gathered (the same on every rank, in block order).
    FieldLevel fl;
    fl.sigma = sigma;
    const std::vector<double> all = gathered ? std::move(packed) : comm.allgather(packed);
    if (!gathered) bytes += static_cast<std::uint64_t>(all.size() * sizeof(double));
    const auto n = static_cast<Eigen::Index>(all.size() / 4);
    fl.centres.resize(n, 3);
    fl.weights.resize(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      for (int a3 = 0; a3 < 3; ++a3) fl.centres(i, a3) = all[static_cast<std::size_t>(4 * i + a3)];
      fl.weights[i] = all[static_cast<std::size_t>(4 * i + 3)];
    }
    // The level's report: counts over the blocks (gathered levels: one rank's, the same everywhere).
    std::int64_t nonZerosAll = 0;
    for (const DistributedLevelReport& dl : dls) nonZerosAll += static_cast<std::int64_t>(dl.nonZeros);
    lr.centres = static_cast<std::size_t>(fl.centres.rows());
    lr.nonZeros = static_cast<std::size_t>(comm.allreduce(gathered ? (me == 0 ? nonZerosAll : 0) : nonZerosAll, ReduceOp::Sum));
    lr.solve.iterations = static_cast<int>(comm.allreduce(static_cast<std::int64_t>(lr.solve.iterations), ReduceOp::Max));
    const bool allConverged = comm.allreduce(static_cast<std::int64_t>(lr.solve.converged ? 0 : 1), ReduceOp::Sum) == 0;
    if (!allConverged && lr.solve.converged) {
      lr.solve.converged = false;
      lr.solve.reason = StopReason::IterationLimit;
    }
    lr.solve.relativeResidual = comm.allreduce(lr.solve.relativeResidual, ReduceOp::Max);
    lr.solve.maxResidual = comm.allreduce(lr.solve.maxResidual, ReduceOp::Max);
    fitted.push_back(std::move(fl));
    evaluator->appendLevel(fitted.back());
    if (k == levels && options.overshootCheck && overshootRound < options.overshootRounds && offSide != 0 &&
        rep.inputPoints > 1) {
      // This rank's candidates: its own points (lp's rows it owns), tested against its data (its points and
      // the halo, which reaches beyond D, or the whole cloud when gathered).
      const auto t0 = Clock::now();
      std::vector<Eigen::Index> ownRows;
      for (Eigen::Index r = 0; r < lp.rows(); ++r) {
        if (gathered ? (r >= firstOwnRow && r < firstOwnRow + u.rows()) : rowBlock[static_cast<std::size_t>(r)] >= 0) ownRows.push_back(r);
      }
      const NeighborIndex dataIndex(lp);
      if (overshootSpacing < 0.0) overshootSpacing = parts == 1 ? spacing : 0.0;  // one block: the winding number's, as fit()
      if (!(overshootSpacing > 0.0)) {
        // The median point area over all ranks' points (a stride sample of at most about 2^18 of them).
        const auto total = static_cast<std::int64_t>(rep.inputPoints);
        const std::int64_t stride = std::max<std::int64_t>(1, total >> 18);
        std::vector<double> sample;
        if (lp.rows() >= 2 && !ownRows.empty()) {  // a rank may own no point of a small cloud
          const Eigen::VectorXd areas = estimatePointAreas(lp, Points(-ln), WindingOptions().areaNeighbors, dataIndex);
          for (std::size_t i = 0; i < ownRows.size(); ++i) {
            if ((ids[i] % stride) == 0) sample.push_back(areas[ownRows[i]]);
          }
        }
        const std::vector<double> gatheredAreas = comm.allgather(sample);
        overshootSpacing = detail::medianSpacing(
            Eigen::Map<const Eigen::VectorXd>(gatheredAreas.data(), static_cast<Eigen::Index>(gatheredAreas.size())));
      }
      const double d = options.overshootSpacings * overshootSpacing;
      std::vector<double> found;  // x, y, z, s·D of this rank's sites
      if (d > 0.0 && std::isfinite(d)) {
        if (!overshootCandidates) {
          overshootCandidates = std::make_unique<detail::OvershootCandidates>(detail::overshootCandidates(lp, ln, ownRows, d, offSide));
        }
        detail::OvershootCandidates& cand = *overshootCandidates;
        for (const std::size_t r : detail::overshootSites(*evaluator, cand, dataIndex, d)) {
          for (int a3 = 0; a3 < 3; ++a3) found.push_back(cand.q(static_cast<Eigen::Index>(r), a3));
          found.push_back(cand.toward[r] * d);
        }
      }
      const std::vector<double> sites = comm.allgather(found);
      if (sites.empty()) {
        overshootSeconds += secondsSince(t0);
      } else {
        // What the check adds: its tests and every pass of level M but the last.
        overshootSeconds += secondsSince(levelStart);
        // Level M again with the sites: it leaves the field, its reports go.
        const Eigen::Index base = overshootAt.rows(), extra = static_cast<Eigen::Index>(sites.size() / 4);
        overshootAt.conservativeResize(base + extra, 3);
        overshootTargets.conservativeResize(base + extra);
        for (Eigen::Index j = 0; j < extra; ++j) {
          for (int a3 = 0; a3 < 3; ++a3) overshootAt(base + j, a3) = sites[static_cast<std::size_t>(4 * j + a3)];
          overshootTargets[base + j] = sites[static_cast<std::size_t>(4 * j + 3)];
        }
        ++overshootRound;
        fitted.pop_back();
        evaluator->dropLastLevel();
        --k;
        continue;
      }
    }
    if (k == levels) {
      lr.overshootSites = static_cast<std::size_t>(overshootAt.rows());
      lr.overshootRounds = overshootRound;
      lr.secondsOvershoot = overshootSeconds;
    }
    rep.levelReports.push_back(lr);
    dls.front().bytes = bytes - bytesBefore;  // the rank's exchanges, on its first block
    // A gathered level is one solve for all of the rank's blocks: reported on the first.
    if (units == 1) dls.front().seconds = secondsSince(levelStart);
    for (int j = 0; j < localBlocks; ++j) mine[static_cast<std::size_t>(j)].levels.push_back(dls[static_cast<std::size_t>(j)]);
  }

  // E_0 at the owned input points and E_δ at the owned finest offset points, from the final field.
  notify(interrupter, FitStage::Errors, 0, levels, "", 100);
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

  // Every block's report on every rank (fixed-size records: a header per block, then its levels).
  struct Flat {
    double v[11];
  };
  std::vector<Flat> flat;
  for (std::size_t j = 0; j < mine.size(); ++j) {
    DistributedRankReport& m = mine[j];
    m.secondsFit = secondsSince(start);
    m.bytesReceived = j == 0 ? bytes : 0;
    m.peakBytes = std::max(m.peakBytes, j + 1 == mine.size() ? peakResidentBytes() : std::uint64_t{0});
    flat.push_back({{static_cast<double>(m.rank), static_cast<double>(m.readRows), static_cast<double>(m.points),
                     static_cast<double>(m.keyBegin), static_cast<double>(m.keyEnd), m.secondsPartition, m.secondsFit,
                     static_cast<double>(m.bytesReceived), static_cast<double>(m.levels.size()), static_cast<double>(m.block),
                     static_cast<double>(m.peakBytes)}});
    for (const DistributedLevelReport& l : m.levels) {
      flat.push_back({{static_cast<double>(l.level) + (l.gathered ? 0.5 : 0.0), static_cast<double>(l.levelPoints),
                       static_cast<double>(l.haloPoints), static_cast<double>(l.unknowns), static_cast<double>(l.ownedCentres),
                       static_cast<double>(l.nonZeros), static_cast<double>(l.iterations), l.seconds,
                       static_cast<double>(l.ghosts), static_cast<double>(l.bytes), l.secondsSolve}});
    }
  }
  const std::vector<Flat> all = comm.allgather(flat);
  drep.rankReports.clear();
  for (std::size_t at = 0; at < all.size();) {
    DistributedRankReport r;
    const Flat& h = all[at++];
    r.rank = static_cast<int>(h.v[0]);
    r.readRows = static_cast<std::size_t>(h.v[1]);
    r.points = static_cast<std::size_t>(h.v[2]);
    r.keyBegin = static_cast<std::uint64_t>(h.v[3]);
    r.keyEnd = static_cast<std::uint64_t>(h.v[4]);
    r.secondsPartition = h.v[5];
    r.secondsFit = h.v[6];
    r.bytesReceived = static_cast<std::uint64_t>(h.v[7]);
    const auto levelsHere = static_cast<std::size_t>(h.v[8]);
    r.block = static_cast<int>(h.v[9]);
    r.peakBytes = static_cast<std::uint64_t>(h.v[10]);
    for (std::size_t i = 0; i < levelsHere && at < all.size(); ++i) {
      const Flat& f = all[at++];
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
  }
  rep.secondsTotal = secondsSince(start);
  return FitResult{std::move(field), std::move(rep), std::move(evaluator)};
}

}  // namespace duplexfit
