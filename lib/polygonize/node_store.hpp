// Sparse storage of sampled grid node values: the node lattice is cut into tiles of T³ nodes
// (T = the coarse step, a power of two), allocated only where nodes were sampled, plus a dense
// array for the coarse lattice (every T-th node and the last node of each axis). Values are floats;
// NaN = not sampled.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace duplexfit::detail {

class NodeStore {
 public:
  /// Marks a node requested for sampling but not yet sampled.
  static constexpr float kPending = std::numeric_limits<float>::infinity();
  static constexpr float kMissing = std::numeric_limits<float>::quiet_NaN();

  /// cells per axis (each ≥ 1), tile edge in nodes (a power of two ≥ 2).
  NodeStore(const Eigen::Vector3i& cells, int tile);

  int tile() const noexcept { return tile_; }
  int cells(int axis) const noexcept { return cells_[axis]; }
  int tiles(int axis) const noexcept { return tiles_[axis]; }
  std::int64_t nodeId(int i, int j, int k) const noexcept {
    return i + nodes_[0] * (j + nodes_[1] * static_cast<std::int64_t>(k));
  }

  /// Tile (tx, ty, tz), or null when it was never allocated.
  const float* tileData(int tx, int ty, int tz) const noexcept {
    return tiles_data_[tileId(tx, ty, tz)].get();
  }
  /// The tile holding node (i, j, k), or null.
  const float* tileOf(int i, int j, int k) const noexcept {
    return tileData(i >> shift_, j >> shift_, k >> shift_);
  }
  /// The tile holding node (i, j, k), allocated on first use (all NaN, coarse values copied in).
  float* ensureTile(int i, int j, int k) {
    float* t = tiles_data_[tileId(i >> shift_, j >> shift_, k >> shift_)].get();
    return t != nullptr ? t : allocateTile(i >> shift_, j >> shift_, k >> shift_);
  }
  /// Offset of node (i, j, k) inside its tile.
  int local(int i, int j, int k) const noexcept {
    return (i & mask_) | ((j & mask_) << shift_) | ((k & mask_) << (2 * shift_));
  }
  std::int64_t allocatedTiles() const noexcept { return allocated_; }
  /// Bytes held by tiles and the coarse lattice.
  std::int64_t bytes() const noexcept {
    return static_cast<std::int64_t>(sizeof(float)) *
           (allocated_ * tile_ * tile_ * tile_ + static_cast<std::int64_t>(coarse_.size()));
  }
  /// Frees all values and marks (the store reads as empty afterwards).
  void release();

  // Cell marks: cell (i, j, k) spans nodes (i..i+1, j..j+1, k..k+1) and is stored with its lowest
  // node. Marked cells are contoured; all their nodes must be sampled.
  void markCell(int i, int j, int k);
  bool cellMarked(int i, int j, int k) const noexcept {
    const std::uint64_t* m = marks_[tileId(i >> shift_, j >> shift_, k >> shift_)].get();
    if (m == nullptr) return false;
    const int l = local(i, j, k);
    return ((m[l >> 6] >> (l & 63)) & 1) != 0;
  }
  /// Marks of cells i0 .. i0 + T − 1 of row (j, k) as bits 0 .. T − 1 (i0 a multiple of T; a row
  /// never straddles two words because T divides 64).
  std::uint64_t rowMarks(int i0, int j, int k) const noexcept {
    const std::uint64_t* m = marks_[tileId(i0 >> shift_, j >> shift_, k >> shift_)].get();
    if (m == nullptr) return 0;
    const int l = local(i0, j, k);
    const std::uint64_t word = m[l >> 6] >> (l & 63);
    return tile_ == 64 ? word : word & ((std::uint64_t{1} << tile_) - 1);
  }

  /// The sampled value of node (i, j, k), NaN when not sampled (or kPending while requested).
  float value(int i, int j, int k) const noexcept {
    const float* t = tileOf(i, j, k);
    return t != nullptr ? t[local(i, j, k)] : coarseValue(i, j, k);
  }

  // Coarse lattice: coarse index c along an axis is node min(c·T, cells).
  int coarseCount(int axis) const noexcept { return coarse_count_[axis]; }
  int coarseNode(int axis, int c) const noexcept {
    return c + 1 == coarse_count_[axis] ? cells_[axis] : c * tile_;
  }
  /// Coarse index of node i along axis, or −1 when i is not on the coarse lattice.
  int coarseIndex(int axis, int i) const noexcept {
    if (i == cells_[axis]) return coarse_count_[axis] - 1;
    return (i & mask_) == 0 ? i >> shift_ : -1;
  }
  /// Allocates the coarse lattice (NaN) for adaptive sampling.
  void allocateCoarse();
  float& coarse(int ci, int cj, int ck) noexcept {
    return coarse_[ci + coarse_count_[0] * (cj + coarse_count_[1] * static_cast<std::size_t>(ck))];
  }

 private:
  float* allocateTile(int tx, int ty, int tz);
  float coarseValue(int i, int j, int k) const noexcept;
  std::size_t tileId(int tx, int ty, int tz) const noexcept {
    return tx +
           static_cast<std::size_t>(tiles_[0]) * (ty + static_cast<std::size_t>(tiles_[1]) * tz);
  }

  int tile_, shift_ = 0, mask_;
  std::array<int, 3> cells_{}, tiles_{}, coarse_count_{};
  std::array<std::int64_t, 2> nodes_{};
  std::vector<std::unique_ptr<float[]>> tiles_data_;
  std::vector<std::unique_ptr<std::uint64_t[]>> marks_;
  std::vector<float> coarse_;
  std::int64_t allocated_ = 0;
};

}  // namespace duplexfit::detail
