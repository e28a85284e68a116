// The fit distributed over the ranks of a Communicator by spatial blocks (docs/method.md, "Distributed
// fit"): every rank owns the points of one Morton range; coarse levels are solved identically on every
// rank from the gathered level points, fine levels by restricted additive Schwarz ("local" mode: each rank
// solves its block plus a halo of g·σ_k and keeps the weights of the centres it owns) or by distributed PCG
// on the level's global system ("exact" mode: each rank holds the rows of its owned centres). The result
// is ONE ImplicitField, held whole by every rank.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "duplexfit/communicator.hpp"
#include "duplexfit/fit.hpp"

namespace duplexfit {

enum class DistributedMode {
  Local,  ///< restricted additive Schwarz: one local solve per block and level, owned weights kept
  /// Distributed PCG on the level's global system (rows of the owned centres, ghost exchange every
  /// iteration, rank-local block Jacobi), the stopping rules of fit()'s solves.
  Exact
};
const char* distributedModeName(DistributedMode mode) noexcept;  ///< "local", "exact"

struct DistributedOptions {
  DistributedMode mode = DistributedMode::Local;
  /// g: a block's system holds the centres derived from level points within g·σ_k of its own; the data
  /// (constraint validity tests, medial points) reach (g + 1)·σ_k + 2·max|δ|. Local mode only (exact mode
  /// takes the data within 2σ_k + 3·max|δ| + 2 cell diagonals and keeps only the owned centres). Default 4
  /// (docs/method.md "Distributed fit": on fandisk_50k at P = 4, E_δ 3.2e-3 at g = 2, 9.9e-6 at g = 4).
  double halo = 4.0;
  /// A level with at most this many level points (all ranks) is gathered and solved on every rank.
  std::size_t coarsePoints = 8192;
  /// P > 1: the sign anchors' winding number is that of a proxy cloud, the gathered cell centroids of the
  /// finest depth with at most this many cells (the whole cloud is on no rank).
  std::size_t windingPoints = 65536;
};

/// One level on one rank.
struct DistributedLevelReport {
  int level = 0;
  bool gathered = false;            ///< solved on every rank from the gathered level points
  std::size_t levelPoints = 0;      ///< level points this rank holds (owned + halo; all when gathered)
  std::size_t haloPoints = 0;       ///< input points received from other ranks for this level
  std::size_t unknowns = 0;         ///< rows of the rank's system (exact mode: its rows of the global one)
  std::size_t ghosts = 0;           ///< exact mode: other ranks' unknowns its rows couple to
  std::size_t ownedCentres = 0;     ///< centres whose weights this rank contributes
  std::size_t nonZeros = 0;
  int iterations = 0;
  std::uint64_t bytes = 0;          ///< received in this level (halo data, gathers; exact: ghost exchanges)
  double seconds = 0.0;             ///< the whole level on this rank
  double secondsSolve = 0.0;        ///< its solve (exact mode: the distributed PCG, waits included)
};

struct DistributedRankReport {
  int rank = 0;
  std::size_t readRows = 0;         ///< rows of the file this rank read
  std::size_t points = 0;           ///< points it owns (after merging duplicates)
  std::uint64_t keyBegin = 0, keyEnd = 0;  ///< its Morton range [begin, end)
  std::vector<DistributedLevelReport> levels;
  double secondsPartition = 0.0, secondsFit = 0.0;
  std::uint64_t bytesReceived = 0;  ///< by the halo exchanges and gathers of the fit
};

struct DistributedReport {
  DistributedMode mode = DistributedMode::Local;
  double halo = 4.0;
  int ranks = 1;
  std::string communicator;
  std::size_t coarsePoints = 0;
  std::uint64_t fileRows = 0;       ///< the vertex rows of the input
  std::uint64_t ownedRows = 0;      ///< rows owned after the redistribution, all ranks
  /// Every file row is owned by exactly one rank: counts and id checksums (Σ id, Σ id²) agree.
  bool ownedOnce = false;
  /// σ_0 from each block's own octree (summed leaf diagonals and counts): exact with one rank, an
  /// approximation where leaves straddle blocks.
  bool sigma0Approximate = false;
  std::size_t windingProxyPoints = 0;  ///< P > 1 with sign anchors: the proxy cloud's points
  std::vector<DistributedRankReport> rankReports;  ///< every rank's, on every rank
};

/// The owned points of this rank and the global facts the distributed fit needs.
struct DistributedPoints {
  PointSet points;                  ///< owned, in file-row order, duplicates merged
  Eigen::AlignedBox3d bounds;       ///< the whole input's bounding box
  std::vector<std::uint64_t> splitters;  ///< the Morton ranges (hierarchy box of the normalised input)
};

/// Partition: each rank hands in its own rows of the file (rows [firstRow, firstRow + rows)); the global
/// bounds come from a reduction, the Morton ranges from a histogram, and the rows move to their owners.
/// Fills report's partition fields and this rank's entry. @throws InvalidArgument (no points anywhere).
DistributedPoints partitionPoints(Communicator& comm, const PointSet& myRows, std::int64_t firstRow,
                                  std::uint64_t fileRows, DistributedReport& report);

/// The fit over the ranks: same options as fit() (offset correction unsupported); every rank gets the
/// whole field; `report` gets the per-rank figures (gathered). `checkPoints` (if not null) receives a
/// proxy of the cloud that every rank holds (gathered cell centroids) for the self-check.
/// With one rank the field is the same as fit()'s. @throws as fit().
FitResult fitDistributed(const Device& device, Communicator& comm, const DistributedPoints& points,
                         const FitOptions& options, const DistributedOptions& distributed, DistributedReport& report,
                         Points* checkPoints = nullptr, Interrupter* interrupter = nullptr);

}  // namespace duplexfit
