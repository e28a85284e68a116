// CellGrid (private to the library): exact fixed-radius neighbour queries over a uniform grid of cubic
// cells. The points are counting-sorted by cell, x fastest, so the cells of one (y, z) row that a query
// reaches are one contiguous run of the sorted points. For a radius about the cell's side (the level
// system's assembly: radius σ, cells of σ; the merge of near-duplicate centres: radius σ/100 in the same
// cells) a query reads 9 runs or fewer, with no tree to build or descend.
//
// The distance is computed as FLANN's L2_3D does it (the query minus the point, squares summed in x, y,
// z order, then the square root) and a point is a hit when that distance is < radius, as in
// NeighborIndex::radiusSearch: the two return the same points with the same distances.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "duplexfit/types.hpp"

namespace duplexfit::detail {

class CellGrid {
 public:
  /// Tables larger than this (4 bytes a cell) are not built: usable() is false.
  static constexpr std::size_t kDefaultMaxCells = std::size_t{1} << 24;

  /// Buckets `points` (each row finite: @throws InvalidArgument naming the row otherwise) in cells of
  /// side `cell` (> 0, finite) over their bounding box. When the table would have more than `maxCells`
  /// cells nothing is stored and usable() is false (the caller falls back to NeighborIndex).
  CellGrid(const Points& points, double cell, std::size_t maxCells = kDefaultMaxCells);

  bool usable() const noexcept { return usable_; }
  std::size_t size() const noexcept { return id_.size(); }

  /// The table as within() reads it (the device assembly uploads it): the box's low corner, 1/cell, the
  /// cells per axis, per cell (x fastest) its first sorted point with one more entry at the end, the
  /// sorted points (x y z each) and their input rows.
  const double* origin() const noexcept { return lo_; }
  double inverseCell() const noexcept { return inv_; }
  const int* cellsPerAxis() const noexcept { return n_; }
  const std::vector<std::uint32_t>& cellStarts() const noexcept { return start_; }
  const std::vector<double>& sortedPoints() const noexcept { return xyz_; }
  const std::vector<Index>& sortedIds() const noexcept { return id_; }

  /// The widened reach and the squared-distance bound within() uses for `radius` (shared with the device
  /// assembly, which repeats its arithmetic).
  static double reachFor(double radius) noexcept { return radius * (1.0 + 1e-6); }
  static double boundFor(double radius) noexcept {
    return std::nextafter(radius * radius * (1.0 + 1e-9), std::numeric_limits<double>::infinity());
  }

  /// Calls visit(index, distance) for every point whose distance from q is < radius, in cell order.
  template <typename Visit>
  void within(const double* q, double radius, Visit&& visit) const {
    if (!usable_ || id_.empty()) return;
    // The cells that [q − r, q + r] meets, with r widened a little so that no rounding of q ± r can drop
    // a cell holding a point whose rounded distance is below the radius (every point is tested below).
    const double reach = reachFor(radius);
    int from[3], to[3];
    for (int a = 0; a < 3; ++a) {
      const double lo = (q[a] - reach - lo_[a]) * inv_, hi = (q[a] + reach - lo_[a]) * inv_;
      if (!(hi >= 0.0) || !(lo < static_cast<double>(n_[a]))) return;  // beyond the box (or NaN)
      from[a] = lo <= 0.0 ? 0 : static_cast<int>(lo);
      to[a] = hi >= static_cast<double>(n_[a] - 1) ? n_[a] - 1 : static_cast<int>(hi);
    }
    const double bound = boundFor(radius);
    const auto nx = static_cast<std::size_t>(n_[0]), ny = static_cast<std::size_t>(n_[1]);
    for (int iz = from[2]; iz <= to[2]; ++iz) {
      for (int iy = from[1]; iy <= to[1]; ++iy) {
        const std::size_t row = (static_cast<std::size_t>(iz) * ny + static_cast<std::size_t>(iy)) * nx;
        const std::uint32_t b = start_[row + static_cast<std::size_t>(from[0])];
        const std::uint32_t e = start_[row + static_cast<std::size_t>(to[0]) + 1];
        for (std::uint32_t k = b; k < e; ++k) {
          const double* p = xyz_.data() + 3 * static_cast<std::size_t>(k);
          const double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
          const double squared = dx * dx + dy * dy + dz * dz;
          if (!(squared < bound)) continue;
          const double d = std::sqrt(squared);
          if (d < radius) visit(id_[k], d);
        }
      }
    }
  }

 private:
  bool usable_ = false;
  double lo_[3] = {0.0, 0.0, 0.0};
  double inv_ = 0.0;
  int n_[3] = {0, 0, 0};
  std::vector<std::uint32_t> start_;  ///< per cell (x fastest) the first sorted point; one more at the end
  std::vector<double> xyz_;           ///< the points sorted by cell, x y z each
  std::vector<Index> id_;             ///< each sorted point's row in the input
};

}  // namespace duplexfit::detail
