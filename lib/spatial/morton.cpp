// Morton codes over a point set's bounding box, and the radix-sorted processing order of batched searches.
#include "spatial/morton.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace duplexfit::detail {

namespace {

/// Spreads the 21 low bits of v to every third bit.
std::uint64_t spread(std::uint64_t v) noexcept {
  v &= 0x1FFFFF;
  v = (v | (v << 32)) & 0x1F00000000FFFFull;
  v = (v | (v << 16)) & 0x1F0000FF0000FFull;
  v = (v | (v << 8)) & 0x100F00F00F00F00Full;
  v = (v | (v << 4)) & 0x10C30C30C30C30C3ull;
  v = (v | (v << 2)) & 0x1249249249249249ull;
  return v;
}

}  // namespace

MortonGrid::MortonGrid(const Points& p, const std::vector<std::size_t>* rows, Box box, int bits)
    : top_(static_cast<double>((std::uint64_t{1} << std::clamp(bits, 1, 21)) - 1)), bits_(std::clamp(bits, 1, 21)) {
  double hi[3];
  for (int a = 0; a < 3; ++a) {
    lo_[a] = std::numeric_limits<double>::infinity();
    hi[a] = -lo_[a];
  }
  auto include = [&](Eigen::Index i) {
    for (int a = 0; a < 3; ++a) {
      lo_[a] = std::min(lo_[a], p(i, a));
      hi[a] = std::max(hi[a], p(i, a));
    }
  };
  if (rows != nullptr) {
    for (const std::size_t r : *rows) include(static_cast<Eigen::Index>(r));
  } else {
    for (Eigen::Index i = 0; i < p.rows(); ++i) include(i);
  }
  if (!(lo_[0] <= hi[0])) {  // no rows
    for (int a = 0; a < 3; ++a) lo_[a] = hi[a] = 0.0;
  }
  if (box == Box::Cube) {
    const double side = std::max(1e-300, std::max({hi[0] - lo_[0], hi[1] - lo_[1], hi[2] - lo_[2]}));
    for (double& e : extent_) e = side;
  } else {
    for (int a = 0; a < 3; ++a) extent_[a] = hi[a] - lo_[a];
  }
}

std::uint64_t MortonGrid::key(const Points& p, Eigen::Index i) const noexcept {
  std::uint64_t code = 0;
  for (int a = 0; a < 3; ++a) {
    const double f = extent_[a] > 0.0 ? (p(i, a) - lo_[a]) / extent_[a] : 0.0;
    code |= spread(static_cast<std::uint64_t>(std::clamp(f, 0.0, 1.0) * top_)) << a;
  }
  return code;
}

std::vector<std::uint32_t> processingOrder(const Points& queries, std::int64_t minQueries) {
  const auto q = static_cast<std::int64_t>(queries.rows());
  if (q < minQueries || q > std::numeric_limits<std::uint32_t>::max()) return {};
  const MortonGrid grid(queries, nullptr, MortonGrid::Box::Fitted, 10);
  std::vector<std::uint32_t> key(static_cast<std::size_t>(q));
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < q; ++i) {
    key[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(grid.key(queries, static_cast<Eigen::Index>(i)));
  }
  std::vector<std::uint32_t> order(static_cast<std::size_t>(q));
  std::vector<std::uint32_t> next(static_cast<std::size_t>(q));
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
  for (int shift = 0; shift < 30; shift += 10) {
    std::vector<std::size_t> bucket(1025, 0);
    for (std::uint32_t i : order) ++bucket[((key[i] >> shift) & 1023u) + 1];
    for (std::size_t d = 1; d < bucket.size(); ++d) bucket[d] += bucket[d - 1];
    for (std::uint32_t i : order) next[bucket[(key[i] >> shift) & 1023u]++] = i;
    order.swap(next);
  }
  return order;
}

}  // namespace duplexfit::detail
