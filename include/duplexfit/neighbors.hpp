// Fixed-radius and k-nearest neighbour queries over a point set (a k-d tree of our own behind a PImpl), with
// sorted, deterministic results: the sparsity pattern of every Wendland system comes from here.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "duplexfit/types.hpp"

namespace duplexfit {

class Interrupter;

/// Neighbour lists of q queries in CSR form: the neighbours of query i are
/// indices[offsets[i] .. offsets[i+1]), with their Euclidean distances, sorted by (distance, index).
struct NeighborLists {
  std::vector<std::int64_t> offsets{0};  ///< q + 1 entries
  std::vector<Index> indices;
  std::vector<double> distances;
  std::size_t queries() const noexcept { return offsets.size() - 1; }
  std::size_t count(std::size_t i) const noexcept {
    return static_cast<std::size_t>(offsets[i + 1] - offsets[i]);
  }
};

/// An exact k-d tree over a fixed set of points (which is copied, so the index owns its data).
class NeighborIndex {
 public:
  /// @throws InvalidArgument when a coordinate is NaN or Inf (naming the row).
  explicit NeighborIndex(const Points& points);
  NeighborIndex(NeighborIndex&&) noexcept;
  NeighborIndex& operator=(NeighborIndex&&) noexcept;
  ~NeighborIndex();

  std::size_t size() const noexcept;
  /// All points p with ‖p − q‖ < radius for each query q (the query itself included when it is in the set).
  /// `interrupter` (may be null) is polled from the calling thread when the search starts and then about
  /// every 20 ms, so that a search over millions of queries can be stopped.
  /// @throws InvalidArgument when radius ≤ 0 or not finite; Cancelled when the interrupter says stop.
  NeighborLists radiusSearch(const Points& queries, double radius, Interrupter* interrupter = nullptr) const;
  /// radiusSearch without sorting each query's hits by (distance, index): the same hits in the tree's
  /// visiting order, which is deterministic, for callers that re-sort or only count (the fit's assembly
  /// sorts each row by column, the merge of near-duplicate centres only asks whether an earlier one is near).
  NeighborLists radiusSearchUnsorted(const Points& queries, double radius, Interrupter* interrupter = nullptr) const;
  /// The k nearest points of each query (fewer when the set is smaller); `interrupter` as for radiusSearch.
  /// @throws InvalidArgument when k ≤ 0; Cancelled.
  NeighborLists knnSearch(const Points& queries, int k, Interrupter* interrupter = nullptr) const;
  /// The nearest point of each query among those at distance ≤ radius (ties by index), or none: knnSearch
  /// with k = 1 whose search never looks beyond the radius, so a query far from every point is cheap. The
  /// bound is rounded up by a few units in the last place (as radiusSearch's), so a caller that needs an
  /// exact ≤ test makes it on the coordinates.
  /// @throws InvalidArgument when radius ≤ 0 or not finite; Cancelled.
  NeighborLists nearestWithin(const Points& queries, double radius, Interrupter* interrupter = nullptr) const;
  /// Whether some point other than exclude[i] (−1: none excluded) lies at distance < radius[i] from query
  /// i: at most one hit a query (one such point, not necessarily the nearest), none where the ball is
  /// empty. The distance is the other searches' (so "no hit" is exactly "the nearest other point's
  /// distance ≥ radius[i]"), and the search stops at the first point found: an emptiness test costs
  /// less than the nearest-point search it replaces (the fit's offset validity test).
  /// @throws InvalidArgument when the sizes differ or a radius is not finite; Cancelled.
  NeighborLists anyOtherWithin(const Points& queries, const std::vector<Index>& exclude,
                               const std::vector<double>& radius, Interrupter* interrupter = nullptr) const;

 private:
  NeighborLists radiusImpl(const Points& queries, double radius, Interrupter* interrupter, bool sorted) const;
  NeighborLists knnImpl(const Points& queries, std::size_t k, double bound, Interrupter* interrupter) const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace duplexfit
