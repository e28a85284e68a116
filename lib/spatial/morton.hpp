// Morton (Z-order) codes and the spatially coherent orders built from them (private to the library): the
// fit's centre order (SpMV locality, block preconditioners), the normal estimation's working order and the
// batched neighbour searches' processing order all come from here.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <omp.h>

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
  // Both passes and the sort's counting and scattering on the team's threads, each over its own contiguous
  // part of the entries (a stable LSD radix sort: a thread's entries of a digit go after those of the
  // threads before it), so the result is the serial one for any team size. fandisk_550k's 3.6M-face meshes:
  // 0.14 s of one thread a call before (every tree build and large field evaluation sorts).
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -lo[a];
  }
  std::vector<std::uint64_t> key(n), next(n);
  constexpr std::size_t kSerial = std::size_t{1} << 16;  // fewer entries: one thread
  const int threads = n >= kSerial ? std::max(1, omp_get_max_threads()) : 1;
  std::vector<std::size_t> buckets(static_cast<std::size_t>(threads) * 1024);  // per thread and digit
  const auto parts = [n](int t, int nt, std::size_t& b, std::size_t& e) {
    b = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(nt);
    e = n * static_cast<std::size_t>(t + 1) / static_cast<std::size_t>(nt);
  };
#pragma omp parallel num_threads(threads)
  {
    const int nt = omp_get_num_threads(), t = omp_get_thread_num();
    std::size_t b = 0, e = 0;
    parts(t, nt, b, e);
    double mlo[3] = {lo[0], lo[1], lo[2]}, mhi[3] = {hi[0], hi[1], hi[2]};
    for (std::size_t i = b; i < e; ++i) {
      double x[3];
      point(i, x);
      for (int a = 0; a < 3; ++a) {
        mlo[a] = std::min(mlo[a], x[a]);
        mhi[a] = std::max(mhi[a], x[a]);
      }
    }
#pragma omp critical(duplexfit_morton_box)
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], mlo[a]);
      hi[a] = std::max(hi[a], mhi[a]);
    }
#pragma omp barrier
    const MortonGrid grid(lo, hi, MortonGrid::Box::Fitted, 10);
    for (std::size_t i = b; i < e; ++i) {
      double x[3];
      point(i, x);
      key[i] = (grid.key(x) << 32) | i;
    }
    for (int shift = 32; shift < 62; shift += 10) {
#pragma omp barrier
      std::size_t* mine = buckets.data() + 1024 * static_cast<std::size_t>(t);
      std::fill(mine, mine + 1024, std::size_t{0});
      for (std::size_t i = b; i < e; ++i) ++mine[(key[i] >> shift) & 1023U];
#pragma omp barrier
#pragma omp single
      {
        std::size_t at = 0;
        for (std::size_t d = 0; d < 1024; ++d) {
          for (int u = 0; u < nt; ++u) {
            std::size_t& c = buckets[1024 * static_cast<std::size_t>(u) + d];
            const std::size_t count = c;
            c = at;
            at += count;
          }
        }
      }
      for (std::size_t i = b; i < e; ++i) next[mine[(key[i] >> shift) & 1023U]++] = key[i];
#pragma omp barrier
#pragma omp single
      key.swap(next);
    }
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
