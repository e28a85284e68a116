// Internal parts of normal estimation shared with the bilateral filter (PCA normals of a cloud).
#pragma once

#include <cstdint>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::detail {

/// Unoriented PCA normals of distinct, finite points (n ≥ k + 1 ≥ 4).
struct PcaNormals {
  Points normals;                       ///< unit, arbitrary sign; zero where the neighbourhood is degenerate
  std::vector<std::uint32_t> neighbors; ///< n·lists entries: the sorted kNN lists (the point first)
  std::size_t listSize = 0;             ///< entries per point in `neighbors`
  std::vector<double> kthDistance;      ///< distance to the k-th neighbour (local sampling radius)
  std::size_t degenerate = 0;
  std::size_t nonPlanar = 0;
  double neighborSeconds = 0.0, pcaSeconds = 0.0;
};

/// PCA over the point and its k nearest neighbours; the kNN lists hold max(k, graphK) + 1 entries (for the
/// orientation graph). Positions are centred on their bounding-box centre before the device sums.
PcaNormals pcaNormals(const Device& device, Precision precision, const Points& points, int k, int graphK);

}  // namespace duplexfit::detail
