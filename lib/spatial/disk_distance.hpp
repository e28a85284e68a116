// Distance to a sampled surface modelled as a soup of disks, one per oriented point (private to the
// library): the targets of the sign anchors and of the offset correction (docs/method.md).
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "duplexfit/types.hpp"

namespace duplexfit {
class NeighborIndex;
struct NeighborLists;
}

namespace duplexfit::detail {

/// The nearest points whose disks the disk-soup distance considers.
constexpr int kDiskNeighbours = 12;

/// Distance from each query to the sampled surface modelled as a soup of disks: point i stands for the
/// disk of radius sqrt(a_i/π) around p_i in its tangent plane (normal n_i); the distance is the smallest
/// over the k nearest points. Accurate to the surface's curvature times the disk radius squared, where
/// the plain nearest-point distance overestimates by about spacing²/(4d).
Eigen::VectorXd diskSoupDistance(const Points& queries, const Points& points, const Points& normals,
                                 const Eigen::VectorXd& areas, const NeighborIndex& index, int k = kDiskNeighbours);

/// The same from each query's nearest points already found (sorted, as NeighborIndex::knnSearch gives
/// them): the first k of each list are used.
Eigen::VectorXd diskSoupDistance(const Points& queries, const Points& points, const Points& normals,
                                 const Eigen::VectorXd& areas, const NeighborLists& nearest, int k = kDiskNeighbours);

}  // namespace duplexfit::detail
