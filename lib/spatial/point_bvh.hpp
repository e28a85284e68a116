// Nearest-other-point queries far from a dense point set (private to the library): the validity test of
// the offset and off-surface companions (docs/method.md §3.1) asks, for q = p_i + step·ν_i, for the nearest
// point of P other than p_i. q lies |step| from a surface sampled much more densely than |step|; a k-d
// tree's cells extend from the surface into the empty space around it, so every leaf whose cell meets the
// ball of radius ≈ |step| is searched, (|step| / spacing)² points a query, which grows with the density.
// A bounding volume hierarchy with tight boxes around the points searches only the boxes that come
// closer than the best distance so far: on a 20M-point fandisk sample at |step| = 0.025 (100 spacings)
// 15 µs a query against the tree's 63 µs; below about 45 spacings the tree is faster (fit/constraints.cpp
// picks one per step; bench/neighbors_bench.cpp measures both).
#pragma once

#include <cstdint>
#include <vector>

#include "duplexfit/types.hpp"

namespace duplexfit {
class Interrupter;
class NeighborIndex;
}

namespace duplexfit::detail {

/// A binary BVH over points in Morton order, with leaves of a few points and conservative float boxes.
class PointBvh {
 public:
  /// @throws InvalidArgument when a coordinate is not finite (naming the row) or beyond 2^31 − 1 points.
  explicit PointBvh(const Points& points);

  std::size_t size() const noexcept { return ids_.size(); }

  /// For each query row i: the nearest point other than exclude[i] (a point index; −1 excludes none),
  /// by (Euclidean distance, index) as NeighborIndex::knnSearch orders its results (bit-identical
  /// distances: the same arithmetic), in distance[i] and nearest[i]; +∞ and −1 when there is none.
  /// `interrupter` (may be null) is polled as NeighborIndex polls it. @throws Cancelled.
  void nearestOther(const Points& queries, const std::vector<Eigen::Index>& exclude, std::vector<double>& distance,
                    std::vector<Eigen::Index>& nearest, Interrupter* interrupter = nullptr) const;

 private:
  struct Node {
    float lo[3], hi[3];
    std::int32_t first, last;  ///< the node's points [first, last) in Morton order
    std::int32_t right;        ///< the right child (the left one is the next node); −1: a leaf
  };
  std::int32_t build(std::int32_t first, std::int32_t last);

  std::vector<double> points_;     ///< x, y, z in Morton order
  std::vector<std::int32_t> ids_;  ///< the input row of each
  std::vector<Node> nodes_;        ///< preorder; nodes_[0] is the root
};

/// The same answer from a k-d tree of the points (its two nearest, without exclude[i]): the search below
/// about 45 spacings, and the reference PointBvh is tested against.
void nearestOtherInTree(const NeighborIndex& tree, const Points& queries, const std::vector<Eigen::Index>& exclude,
                        std::vector<double>& distance, std::vector<Eigen::Index>& nearest,
                        Interrupter* interrupter = nullptr);

}  // namespace duplexfit::detail
