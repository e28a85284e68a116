// The object-median split and node counts shared by the library's bounding-volume trees (TriangleBvh, the pair search's box
// tree): private to the library.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <map>

namespace duplexfit::measure_detail {

/// Splits order[begin, end) at its middle along the longest axis of the centroids' extent [lo, hi]: the
/// first half gets the entries of smaller centroid coordinate (ties by entry), and the middle is returned.
/// `centroids` holds 3 reals per entry.
template <typename Real>
std::size_t medianSplit(std::uint32_t* order, std::size_t begin, std::size_t end, const Real* centroids,
                        const Real lo[3], const Real hi[3]) {
  int axis = 0;
  for (int k = 1; k < 3; ++k) {
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  }
  const std::size_t mid = begin + (end - begin) / 2;
  std::nth_element(order + begin, order + mid, order + end, [centroids, axis](std::uint32_t x, std::uint32_t y) {
    const Real cx = centroids[3 * std::size_t{x} + static_cast<std::size_t>(axis)];
    const Real cy = centroids[3 * std::size_t{y} + static_cast<std::size_t>(axis)];
    return cx != cy ? cx < cy : x < y;
  });
  return mid;
}

/// Node counts of median-split trees with at most `leaf` entries a leaf, by entry count (two distinct sizes
/// a level, so the table stays small): a subtree of n entries takes counts(n) nodes, laid out depth-first.
class MedianSplitCounts {
 public:
  MedianSplitCounts(std::size_t n, std::size_t leaf) : leaf_(leaf) { count(n); }
  std::size_t operator()(std::size_t n) const { return n <= leaf_ ? 1 : memo_.at(n); }
  int depth(std::size_t n) const { return n <= leaf_ ? 1 : 1 + std::max(depth(n / 2), depth(n - n / 2)); }

 private:
  std::size_t count(std::size_t n) {
    if (n <= leaf_) return 1;
    const auto it = memo_.find(n);
    if (it != memo_.end()) return it->second;
    const std::size_t c = 1 + count(n / 2) + count(n - n / 2);
    memo_[n] = c;
    return c;
  }
  std::size_t leaf_;
  std::map<std::size_t, std::size_t> memo_;
};

}  // namespace duplexfit::measure_detail
