// The spatial decomposition of the distributed fit (docs/method.md, "Distributed fit"): Morton keys over the
// hierarchy box, blocks as Morton ranges balanced by point count, and the halo exchange.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/communicator.hpp"
#include "duplexfit/types.hpp"
#include "fit/hierarchy.hpp"

namespace duplexfit::detail {

/// The 63-bit Morton key of p in 2^21 cells per axis over `box` (bit b of axis a at bit 3b + a), p clamped
/// into the box.
std::uint64_t mortonKey63(const Eigen::Vector3d& p, const HierarchyBox& box) noexcept;

/// The rows of `positions` (normalised) in the order of their mortonKey63 over `box`, ties in row order: the
/// order in which the fit and each block of the distributed fit process their points.
std::vector<Eigen::Index> mortonOrder(const Points& positions, const HierarchyBox& box);

/// B + 1 splitters 0 = s_0 ≤ s_1 ≤ … ≤ s_B = 2^63 for B = `parts` (0: the number of ranks P): part b owns
/// the keys [s_b, s_{b+1}). Chosen from a histogram of the keys' top `histogramBits` bits (reduced over the
/// ranks) so that each part's count is within one histogram bucket of N/B.
std::vector<std::uint64_t> balancedSplitters(Communicator& comm, const std::vector<std::uint64_t>& keys,
                                             int histogramBits = 18, int parts = 0);

/// The first of rank r's blocks when B blocks are shared by P ranks: ⌊r·B/P⌋ (rank r holds the blocks
/// [firstBlockOfRank(r), firstBlockOfRank(r + 1))).
int firstBlockOfRank(int rank, int ranks, int blocks) noexcept;

/// Rows of `positions` within `radius` of the rows flagged in `core` (a superset: every row in a grid cell
/// of side ≥ radius next to a cell holding a flagged row), flagged rows included, in row order. The same
/// cells as exchangeHalo, so a block of one process gets the data a rank owning that block would.
std::vector<Eigen::Index> rowsNear(const Points& positions, const std::vector<char>& core, const HierarchyBox& box,
                                   double radius);

/// The rank whose range holds `key`.
int ownerOfKey(const std::vector<std::uint64_t>& splitters, std::uint64_t key) noexcept;

/// Rows moved to their owners: each rank sends its rows to the owner of their key; rows arrive in
/// (source rank, source row) order.
struct OwnedRows {
  Points positions, normals;
  std::vector<std::int64_t> ids;  ///< the ids given with the rows (file rows)
};
OwnedRows redistribute(Communicator& comm, const Points& positions, const Points& normals,
                       const std::vector<std::int64_t>& ids, const std::vector<std::uint64_t>& keys,
                       const std::vector<std::uint64_t>& splitters);

/// The other ranks' rows within `radius` of this rank's rows (a superset: every row of another rank that
/// lies in a grid cell of side ≥ radius next to a cell holding a row of this one), with their ids; rows
/// arrive in (source rank, source row) order.
OwnedRows exchangeHalo(Communicator& comm, const Points& positions, const Points& normals,
                       const std::vector<std::int64_t>& ids, const HierarchyBox& box, double radius);

/// Per-cell partial sums of a depth-`depth` cell grid over `box` (the cells of cellCentroids).
struct CellSum {
  std::uint64_t key = 0;
  double count = 0.0;
  double position[3] = {0, 0, 0};
  double normal[3] = {0, 0, 0};
};
std::vector<CellSum> cellSums(const Points& points, const Points& normals, const HierarchyBox& box, int depth);

/// The level points of depth `depth` from every rank's cell sums (identical on every rank, sorted by cell
/// key; with one rank the same as cellCentroids).
LevelPoints gatheredCentroids(Communicator& comm, const Points& points, const Points& normals, const HierarchyBox& box,
                              int depth);

}  // namespace duplexfit::detail
