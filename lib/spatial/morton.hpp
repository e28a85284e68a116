// Morton (Z-order) codes and the spatially coherent orders built from them (private to the library): the
// fit's centre order (SpMV locality, block preconditioners), the normal estimation's working order and the
// batched neighbour searches' processing order all come from here.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "duplexfit/types.hpp"

namespace duplexfit::detail {

/// Spreads the 21 low bits of v to every third bit.
constexpr std::uint64_t spreadBits(std::uint64_t v) noexcept {
  v &= 0x1FFFFF;
  v = (v | (v << 32)) & 0x1F00000000FFFFull;
  v = (v | (v << 16)) & 0x1F0000FF0000FFull;
  v = (v | (v << 8)) & 0x100F00F00F00F00Full;
  v = (v | (v << 4)) & 0x10C30C30C30C30C3ull;
  v = (v | (v << 2)) & 0x1249249249249249ull;
  return v;
}

/// A grid of 2^bits cells per axis over the bounding box of a point set, mapping points to Morton codes
/// (bit b of axis a at bit 3b + a).
class MortonGrid {
 public:
  enum class Box {
    Cube,   ///< one scale for every axis: the box's largest side (a cube anchored at its min corner)
    Fitted  ///< each axis over its own extent (a flat axis maps to cell 0)
  };
  /// Over the rows `rows` of p (every row when null); 1 ≤ bits ≤ 21.
  MortonGrid(const Points& p, const std::vector<std::size_t>* rows, Box box, int bits = 21);
  /// Over the box [lo, hi] (lo > hi on some axis: an empty set, mapped to cell 0); 1 ≤ bits ≤ 21.
  MortonGrid(const double lo[3], const double hi[3], Box box, int bits = 21);
  /// The code of row i of p (any row, inside the box or clamped to it).
  std::uint64_t key(const Points& p, Eigen::Index i) const noexcept {
    const double x[3] = {p(i, 0), p(i, 1), p(i, 2)};
    return key(x);
  }
  /// The code of point x (inside the box or clamped to it).
  std::uint64_t key(const double x[3]) const noexcept {
    std::uint64_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const double f = extent_[a] > 0.0 ? (x[a] - lo_[a]) / extent_[a] : 0.0;
      code |= spreadBits(static_cast<std::uint64_t>(std::clamp(f, 0.0, 1.0) * top_)) << a;
    }
    return code;
  }

 private:
  double lo_[3] = {0, 0, 0};
  double extent_[3] = {0, 0, 0};  ///< 0: flat axis
  double top_ = 0.0;              ///< 2^bits − 1
  int bits_ = 21;
  void setBox(const double lo[3], const double hi[3], Box box);
};

/// Entries 0..n−1 sorted by the Morton code of point(i, x) (x: 3 coordinates) in a 1024³ grid over the
/// points' bounding box (MortonGrid, Box::Fitted, LSD radix sort of three 10-bit digits), ties in entry
/// order, as keys code << 32 | entry. Two passes over the points: their box, then the codes.
template <typename PointOf>
std::vector<std::uint64_t> mortonSortedKeys(std::size_t n, PointOf point) {
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -lo[a];
  }
  for (std::size_t i = 0; i < n; ++i) {
    double x[3];
    point(i, x);
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], x[a]);
      hi[a] = std::max(hi[a], x[a]);
    }
  }
  const MortonGrid grid(lo, hi, MortonGrid::Box::Fitted, 10);
  std::vector<std::uint64_t> key(n);
  for (std::size_t i = 0; i < n; ++i) {
    double x[3];
    point(i, x);
    key[i] = (grid.key(x) << 32) | i;
  }
  std::vector<std::uint64_t> next(n);
  for (int shift = 32; shift < 62; shift += 10) {
    std::size_t bucket[1025] = {};
    for (const std::uint64_t k : key) ++bucket[((k >> shift) & 1023U) + 1];
    for (std::size_t d = 1; d <= 1024; ++d) bucket[d] += bucket[d - 1];
    for (const std::uint64_t k : key) next[bucket[(k >> shift) & 1023U]++] = k;
    key.swap(next);
  }
  return key;
}

/// For trees over Morton-sorted entries (TriangleBvh, the pair search's box tree): where the sorted
/// codes[begin, end) (at least two) split, the first one with the highest bit in which the range's codes
/// differ set (an octree-like split), or the middle when they are all equal. Both sides are non-empty.
inline std::size_t radixSplit(const std::uint32_t* codes, std::size_t begin, std::size_t end) {
  const std::uint32_t first = codes[begin], last = codes[end - 1];
  if (first == last) return begin + (end - begin) / 2;
  int bit = 31;
  while (((first ^ last) >> bit) == 0) --bit;
  const std::uint32_t upper = last & ~((std::uint32_t{1} << bit) - 1U);
  return static_cast<std::size_t>(std::lower_bound(codes + begin, codes + end, upper) - codes);
}

/// The deepest level of such a tree with leaves of at least one entry: 30 radix splits, then middle
/// splits of at most 2^32 equal codes.
constexpr int kMortonTreeDepth = 30 + 33;

/// The indices of the queries sorted by the Morton code of their cell in a 1024³ grid over the queries'
/// bounding box (LSD radix sort, three 10-bit digits), for batched searches whose consecutive queries
/// should walk the same part of a tree. Empty (meaning the input order) below minQueries queries or
/// beyond 2^32 − 1 of them.
std::vector<std::uint32_t> processingOrder(const Points& queries, std::int64_t minQueries);

}  // namespace duplexfit::detail
