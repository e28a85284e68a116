// Morton codes over a point set's bounding box, and the radix-sorted processing order of batched searches.
#include "spatial/morton.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace duplexfit::detail {

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
  setBox(lo_, hi, box);
}

MortonGrid::MortonGrid(const double lo[3], const double hi[3], Box box, int bits)
    : top_(static_cast<double>((std::uint64_t{1} << std::clamp(bits, 1, 21)) - 1)), bits_(std::clamp(bits, 1, 21)) {
  setBox(lo, hi, box);
}

void MortonGrid::setBox(const double lo[3], const double hi[3], Box box) {
  double top[3];
  for (int a = 0; a < 3; ++a) {
    lo_[a] = lo[a];
    top[a] = hi[a];
  }
  if (!(lo_[0] <= top[0])) {  // no points
    for (int a = 0; a < 3; ++a) lo_[a] = top[a] = 0.0;
  }
  if (box == Box::Cube) {
    const double side = std::max(1e-300, std::max({top[0] - lo_[0], top[1] - lo_[1], top[2] - lo_[2]}));
    for (double& e : extent_) e = side;
  } else {
    for (int a = 0; a < 3; ++a) extent_[a] = top[a] - lo_[a];
  }
}

std::vector<std::uint32_t> processingOrder(const Points& queries, std::int64_t minQueries) {
  const auto q = static_cast<std::int64_t>(queries.rows());
  if (q < minQueries || q > std::numeric_limits<std::uint32_t>::max()) return {};
  const std::vector<std::uint64_t> key = mortonSortedKeys(static_cast<std::size_t>(q), [&queries](std::size_t i, double* x) {
    for (int a = 0; a < 3; ++a) x[a] = queries(static_cast<Eigen::Index>(i), a);
  });
  std::vector<std::uint32_t> order(key.size());
  for (std::size_t i = 0; i < key.size(); ++i) order[i] = static_cast<std::uint32_t>(key[i] & 0xffffffffU);
  return order;
}

}  // namespace duplexfit::detail
