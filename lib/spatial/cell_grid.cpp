// CellGrid: see cell_grid.hpp. The build is a counting sort by cell (two passes over the points).
#include "spatial/cell_grid.hpp"

#include <algorithm>
#include <string>

#include "duplexfit/error.hpp"

namespace duplexfit::detail {

CellGrid::CellGrid(const Points& points, double cell, std::size_t maxCells) {
  if (!(cell > 0.0) || !std::isfinite(cell)) throw InvalidArgument("CellGrid: the cell must be positive and finite");
  const Eigen::Index n = points.rows();
  if (n > static_cast<Eigen::Index>(std::numeric_limits<Index>::max())) {
    throw InvalidArgument("CellGrid: " + std::to_string(n) + " points exceed 2^31 - 1");
  }
  // Cell numbers and per-axis counts fit 32-bit and int arithmetic.
  maxCells = std::min<std::size_t>(maxCells, static_cast<std::size_t>(std::numeric_limits<int>::max()) - 1);
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -std::numeric_limits<double>::infinity();
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double v = points(i, a);
      if (!std::isfinite(v)) {
        throw InvalidArgument("CellGrid: point row " + std::to_string(i) + " has a non-finite coordinate");
      }
      lo[a] = std::min(lo[a], v);
      hi[a] = std::max(hi[a], v);
    }
  }
  if (n == 0) {
    usable_ = true;
    return;
  }
  inv_ = 1.0 / cell;
  std::size_t cells = 1;
  for (int a = 0; a < 3; ++a) {
    const double count = std::floor((hi[a] - lo[a]) * inv_) + 1.0;
    if (!(count <= static_cast<double>(maxCells))) return;  // not usable (also guards the int below)
    n_[a] = static_cast<int>(count);
    lo_[a] = lo[a];
    cells *= static_cast<std::size_t>(n_[a]);
    if (cells > maxCells) return;
  }
  const auto nx = static_cast<std::size_t>(n_[0]), ny = static_cast<std::size_t>(n_[1]);
  const auto cellOf = [&](Eigen::Index i) {
    std::size_t c[3];
    for (int a = 0; a < 3; ++a) {
      // (v − lo)·inv ≥ 0; the top row of the box can round to n: clamped.
      const auto k = static_cast<std::size_t>((points(i, a) - lo_[a]) * inv_);
      c[a] = std::min(k, static_cast<std::size_t>(n_[a] - 1));
    }
    return (c[2] * ny + c[1]) * nx + c[0];
  };
  std::vector<std::uint32_t> slot(static_cast<std::size_t>(n));
  start_.assign(cells + 1, 0);
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::size_t c = cellOf(i);
    slot[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(c);  // the cell, for now
    ++start_[c + 1];
  }
  for (std::size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
  xyz_.resize(3 * static_cast<std::size_t>(n));
  id_.resize(static_cast<std::size_t>(n));
  std::vector<std::uint32_t> next(start_.begin(), start_.end() - 1);
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::uint32_t s = next[slot[static_cast<std::size_t>(i)]]++;
    for (int a = 0; a < 3; ++a) xyz_[3 * static_cast<std::size_t>(s) + static_cast<std::size_t>(a)] = points(i, a);
    id_[s] = static_cast<Index>(i);
  }
  usable_ = true;
}

}  // namespace duplexfit::detail
