// The fit distributed over the ranks of a Communicator by spatial blocks (docs/method.md, "Distributed
// fit"): every rank owns the points of one Morton range; coarse levels are solved identically on every
// rank from the gathered level points, fine levels by restricted additive Schwarz ("local" mode: each rank
// solves its block plus a halo of g·σ_k and keeps the weights of the centres it owns) or by distributed PCG
// on the level's global system ("exact" mode: each rank holds the rows of its owned centres). The result
// is ONE ImplicitField, held whole by every rank.
//
// Blocks (`--blocks N`, out of core): the same decomposition into N blocks, shared by the ranks (one
// process: all N), each rank solving its blocks one after another, so that only one block's system is in
// memory at a time. N blocks in one process give the field of N ranks (the same blocks, halos and rules).
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
  /// Spatial blocks in all, shared by the ranks (0: one per rank). A rank solves its blocks one after
  /// another, each a system of its own, so that the peak memory is about the input, the field and ONE
  /// block's system: `duplexfit fit --blocks N` fits clouds whose single system would not fit in memory.
  /// Local mode only when blocks ≠ ranks; at least one block per rank.
  int blocks = 0;
  /// P > 1 or several blocks: the sign anchors' winding number is that of a proxy cloud, the gathered cell centroids of the
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

/// One block (with one block per rank: one rank).
struct DistributedRankReport {
  int rank = 0;
  int block = 0;                    ///< its index among all blocks (the rank's with one block per rank)
  std::size_t readRows = 0;         ///< rows of the file its rank read (on the rank's first block; else 0)
  std::size_t points = 0;           ///< points it owns (after merging duplicates)
  std::uint64_t keyBegin = 0, keyEnd = 0;  ///< its Morton range [begin, end)
  std::vector<DistributedLevelReport> levels;
  double secondsPartition = 0.0;    ///< its rank's partition
  double secondsFit = 0.0;          ///< its rank's whole fit (all of the rank's blocks)
  std::uint64_t bytesReceived = 0;  ///< by its rank's halo exchanges and gathers (on the rank's first block)
  /// The process's peak resident memory (getrusage) once this block's levels are solved: with blocks in
  /// one process it shows whether the peak grows with the blocks solved.
  std::uint64_t peakBytes = 0;
};

struct DistributedReport {
  DistributedMode mode = DistributedMode::Local;
  double halo = 4.0;
  int ranks = 1;
  int blocks = 1;                   ///< blocks in all (≥ ranks)
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
  std::vector<DistributedRankReport> rankReports;  ///< every block's (rank, then block order), on every rank
};

/// The owned points of this rank and the global facts the distributed fit needs.
struct DistributedPoints {
  /// Owned, duplicates merged, block by block (the rank's blocks in order), in file-row order within a block.
  PointSet points;
  Eigen::AlignedBox3d bounds;       ///< the whole input's bounding box
  std::vector<std::uint64_t> splitters;  ///< the ranks' Morton ranges (hierarchy box of the normalised input)
  std::vector<std::uint64_t> blockSplitters;  ///< the blocks' Morton ranges (the ranks' when one block each)
  int firstBlock = 0;               ///< this rank's first block
  /// Rows of `points` of this rank's blocks: block firstBlock + j holds [blockRows[j], blockRows[j + 1]).
  std::vector<Eigen::Index> blockRows;
};

/// Partition: each rank hands in its own rows of the file (rows [firstRow, firstRow + rows)); the global
/// bounds come from a reduction, the Morton ranges of `blocks` blocks (0: one per rank) from a histogram,
/// and the rows move to the rank holding their block. Fills report's partition fields and this rank's
/// entries. @throws InvalidArgument (no points anywhere, fewer blocks than ranks).
DistributedPoints partitionPoints(Communicator& comm, const PointSet& myRows, std::int64_t firstRow,
                                  std::uint64_t fileRows, DistributedReport& report, int blocks = 0);

/// The fit over the ranks: same options as fit() (offset correction unsupported); every rank gets the
/// whole field; `report` gets the per-rank figures (gathered). `checkPoints` (if not null) receives a
/// proxy of the cloud that every rank holds (gathered cell centroids) for the self-check.
/// With one rank the field is the same as fit()'s. @throws as fit().
FitResult fitDistributed(const Device& device, Communicator& comm, const DistributedPoints& points,
                         const FitOptions& options, const DistributedOptions& distributed, DistributedReport& report,
                         Points* checkPoints = nullptr, Interrupter* interrupter = nullptr);

}  // namespace duplexfit
