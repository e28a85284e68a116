// Morton (Z-order) codes and the spatially coherent orders built from them (private to the library): the
// fit's centre order (SpMV locality, block preconditioners), the normal estimation's working order and the
// batched neighbour searches' processing order all come from here.
#pragma once

#include <cstdint>
#include <vector>

#include "duplexfit/types.hpp"

namespace duplexfit::detail {

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
  /// The code of row i of p (any row, inside the box or clamped to it).
  std::uint64_t key(const Points& p, Eigen::Index i) const noexcept;

 private:
  double lo_[3] = {0, 0, 0};
  double extent_[3] = {0, 0, 0};  ///< 0: flat axis
  double top_ = 0.0;              ///< 2^bits − 1
  int bits_ = 21;
};

/// The indices of the queries sorted by the Morton code of their cell in a 1024³ grid over the queries'
/// bounding box (LSD radix sort, three 10-bit digits), for batched searches whose consecutive queries
/// should walk the same part of a tree. Empty (meaning the input order) below minQueries queries or
/// beyond 2^32 − 1 of them.
std::vector<std::uint32_t> processingOrder(const Points& queries, std::int64_t minQueries);

}  // namespace duplexfit::detail
