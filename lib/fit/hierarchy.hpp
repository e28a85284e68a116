// The octree hierarchy of the fit (docs/method.md §4): the enlarged bounding box, σ_0 from an adaptive
// octree, the number of levels M, and the per-level point sets (cell centroids with averaged normals).
#pragma once

#include <Eigen/Core>

#include "duplexfit/types.hpp"

namespace duplexfit::detail {

struct HierarchyBox {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  double diagonal = 0.0;  ///< L = ‖max − min‖
};

/// The bounding box of the points enlarged by 1e-9·L; zero extents are raised to 1e-3·L (§4.1).
HierarchyBox hierarchyBox(const Points& points);

/// σ_0 = 0.75 × the mean diagonal of the non-empty leaves of an adaptive octree over the box that splits
/// cells holding more than `maxPerLeaf` points, depth capped at 21 (§4.5).
double adaptiveSigma0(const Points& points, const HierarchyBox& box, int maxPerLeaf = 8);

/// The two sums behind adaptiveSigma0: the non-empty leaves' diagonals and their number (the distributed
/// fit reduces them over the ranks' blocks).
void adaptiveOctreeSums(const Points& points, const HierarchyBox& box, double& diagonalSum, std::size_t& leaves,
                        int maxPerLeaf = 8);

/// M = max(1, ⌈log₂(2σ_1/σ_0)⌉) (§4.6).
int levelCount(double sigma1, double sigma0);

/// A level's points: one per non-empty depth-k cell, at the centroid of its points, with the normalised
/// sum of their normals (zero when ‖Σν‖ ≤ 1e-6·count, §3.3). Deterministic order (by cell key).
struct LevelPoints {
  Points positions;
  Points normals;
};
LevelPoints cellCentroids(const Points& points, const Points& normals, const HierarchyBox& box, int depth);

}  // namespace duplexfit::detail
