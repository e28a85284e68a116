// CellGrid (private to the library): exact fixed-radius neighbour queries over a uniform grid of cubic
// cells. The points are counting-sorted by cell, x fastest, so the cells of one (y, z) row that a query
// reaches are one contiguous run of the sorted points. For a radius about the cell's side (the level
// system's assembly: radius σ, cells of σ; the merge of near-duplicate centres: radius σ/100 in the same
// cells) a query reads 9 runs or fewer, with no tree to build or descend.
//
// The distance is computed as NeighborIndex (and FLANN's L2_3D before it) does it (the query minus the point, squares summed in x, y,
// z order, then the square root) and a point is a hit when that distance is < radius, as in
// NeighborIndex::radiusSearch: the two return the same points with the same distances.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "duplexfit/types.hpp"
#include "core/default_init.hpp"
#include "spatial/squared_distance.hpp"

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
    withinSquared(q, radius, [&visit](Index id, double squared) { visit(id, std::sqrt(squared)); });
  }

  /// The same points as within(), each with its squared distance (the distance is its square root). The
  /// square root is taken only where the squared distance alone cannot decide a hit (within a few
  /// roundings of radius²).
  template <typename Visit>
  void withinSquared(const double* q, double radius, Visit&& visit) const {
    const double bound = boundFor(radius), sure = sureBelow(radius);
    forRuns(q, radius, [&](std::uint32_t b, std::uint32_t e) {
      for (std::uint32_t k = b; k < e; ++k) {
        const double squared = squaredTo(q, k);
        if (!(squared < bound)) continue;
        if (squared < sure || std::sqrt(squared) < radius) visit(id_[k], squared);
      }
    });
  }

  /// A hit of collect(): a point's input row and its squared distance from the query.
  struct Hit {
    Index id;
    double squared;
  };

  /// withinSquared()'s hits, in the same order, written to out[at …] (out grows as needed; entries past
  /// the hits are scratch); returns their number. Every candidate is written and the slot kept only for a
  /// hit, so the loop has no branch that depends on the distance (the level assembly's hot loop: about
  /// one candidate in six is a hit there, which a branch mispredicts).
  std::size_t collect(const double* q, double radius, ScratchVector<Hit>& out, std::size_t at) const {
    std::size_t candidates = 0;
    forRuns(q, radius, [&candidates](std::uint32_t b, std::uint32_t e) { candidates += e - b; });
    if (out.size() < at + candidates) out.resize(std::max(2 * out.size(), at + candidates + 4096));
    const double bound = boundFor(radius), sure = sureBelow(radius);
    Hit* o = out.data() + at;
    std::size_t n = 0;
    forRuns(q, radius, [&](std::uint32_t b, std::uint32_t e) {
      for (std::uint32_t k = b; k < e; ++k) {
        const double squared = squaredTo(q, k);
        o[n].id = id_[k];
        o[n].squared = squared;
        n += squared < sure ? 1 : 0;
        // Within a few roundings of radius² (hardly ever): the square root decides, as in withinSquared.
        // One branch on both bounds (&, not &&), almost never taken, so it is predicted.
        if (__builtin_expect((squared >= sure) & (squared < bound), 0)) n += std::sqrt(squared) < radius ? 1 : 0;
      }
    });
    return n;
  }

  /// A squared distance below this has a (correctly rounded) square root below `radius`: radius² less a
  /// relative 1e-12, far more than the roundings of radius² and of the square root (a few 1e-16).
  static double sureBelow(double radius) noexcept { return radius * radius * (1.0 - 1e-12); }

 private:
  /// The squared distance from q to sorted point k, as NeighborIndex sums it.
  double squaredTo(const double* q, std::uint32_t k) const noexcept {
    return squaredDistance(q, xyz_.data() + 3 * static_cast<std::size_t>(k));
  }

  /// Calls run(begin, end) for the sorted points of each (y, z) row of cells that [q − r, q + r] meets.
  template <typename Run>
  void forRuns(const double* q, double radius, Run&& run) const {
    if (!usable_ || id_.empty()) return;
    // The cells that [q − r, q + r] meets, with r widened a little so that no rounding of q ± r can drop
    // a cell holding a point whose rounded distance is below the radius (every point is tested).
    const double reach = reachFor(radius);
    int from[3], to[3];
    for (int a = 0; a < 3; ++a) {
      const double lo = (q[a] - reach - lo_[a]) * inv_, hi = (q[a] + reach - lo_[a]) * inv_;
      if (!(hi >= 0.0) || !(lo < static_cast<double>(n_[a]))) return;  // beyond the box (or NaN)
      from[a] = lo <= 0.0 ? 0 : static_cast<int>(lo);
      to[a] = hi >= static_cast<double>(n_[a] - 1) ? n_[a] - 1 : static_cast<int>(hi);
    }
    const auto nx = static_cast<std::size_t>(n_[0]), ny = static_cast<std::size_t>(n_[1]);
    for (int iz = from[2]; iz <= to[2]; ++iz) {
      for (int iy = from[1]; iy <= to[1]; ++iy) {
        const std::size_t row = (static_cast<std::size_t>(iz) * ny + static_cast<std::size_t>(iy)) * nx;
        run(start_[row + static_cast<std::size_t>(from[0])], start_[row + static_cast<std::size_t>(to[0]) + 1]);
      }
    }
  }

  bool usable_ = false;
  double lo_[3] = {0.0, 0.0, 0.0};
  double inv_ = 0.0;
  int n_[3] = {0, 0, 0};
  std::vector<std::uint32_t> start_;  ///< per cell (x fastest) the first sorted point; one more at the end
  std::vector<double> xyz_;           ///< the points sorted by cell, x y z each
  std::vector<Index> id_;             ///< each sorted point's row in the input
};

}  // namespace duplexfit::detail
