// NodeStore: tiled sparse node values for polygonisation (see node_store.hpp).
#include "node_store.hpp"

#include <algorithm>

namespace duplexfit::detail {

NodeStore::NodeStore(const Eigen::Vector3i& cells, int tile) : tile_(tile), mask_(tile - 1) {
  while ((1 << shift_) < tile_) ++shift_;
  std::size_t tileCount = 1;
  for (int a = 0; a < 3; ++a) {
    cells_[a] = cells(a);
    tiles_[a] = cells_[a] / tile_ + 1;  // nodes 0..cells
    // Coarse nodes: multiples of the tile edge below cells, then cells itself.
    coarse_count_[a] = (cells_[a] + tile_ - 1) / tile_ + 1;
    tileCount *= static_cast<std::size_t>(tiles_[a]);
  }
  nodes_ = {cells_[0] + 1, cells_[1] + 1};
  tiles_data_.resize(tileCount);
  marks_.resize(tileCount);
}

void NodeStore::release() {
  for (auto& t : tiles_data_) t.reset();
  for (auto& m : marks_) m.reset();
  std::vector<float>().swap(coarse_);
  allocated_ = 0;
}

void NodeStore::markCell(int i, int j, int k) {
  std::unique_ptr<std::uint64_t[]>& m = marks_[tileId(i >> shift_, j >> shift_, k >> shift_)];
  if (!m) {
    const std::size_t words = std::max<std::size_t>(1, (std::size_t{1} << (3 * shift_)) / 64);
    m = std::make_unique<std::uint64_t[]>(words);  // zero-initialised
  }
  const int l = local(i, j, k);
  m[l >> 6] |= std::uint64_t{1} << (l & 63);
}

void NodeStore::allocateCoarse() {
  coarse_.assign(static_cast<std::size_t>(coarse_count_[0]) * coarse_count_[1] * coarse_count_[2],
                 kMissing);
}

float* NodeStore::allocateTile(int tx, int ty, int tz) {
  std::unique_ptr<float[]>& slot = tiles_data_[tileId(tx, ty, tz)];
  const std::size_t size = static_cast<std::size_t>(tile_) * tile_ * tile_;
  slot = std::make_unique<float[]>(size);
  std::fill(slot.get(), slot.get() + size, kMissing);
  ++allocated_;
  if (!coarse_.empty()) {
    // Copy the coarse lattice nodes that fall into this tile: its first node and, on the last
    // tile of an axis, the last grid node.
    const int base[3] = {tx * tile_, ty * tile_, tz * tile_};
    int list[3][2];
    int counts[3];
    for (int a = 0; a < 3; ++a) {
      counts[a] = 0;
      list[a][counts[a]++] = base[a];
      if (cells_[a] != base[a] && cells_[a] < base[a] + tile_) list[a][counts[a]++] = cells_[a];
    }
    for (int c = 0; c < counts[2]; ++c) {
      for (int b = 0; b < counts[1]; ++b) {
        for (int a = 0; a < counts[0]; ++a) {
          const int x = list[0][a], y = list[1][b], z = list[2][c];
          slot[static_cast<std::size_t>(local(x, y, z))] =
              coarse(coarseIndex(0, x), coarseIndex(1, y), coarseIndex(2, z));
        }
      }
    }
  }
  return slot.get();
}

float NodeStore::coarseValue(int i, int j, int k) const noexcept {
  if (coarse_.empty()) return kMissing;
  const int ci = coarseIndex(0, i), cj = coarseIndex(1, j), ck = coarseIndex(2, k);
  if (ci < 0 || cj < 0 || ck < 0) return kMissing;
  return coarse_[ci + coarse_count_[0] * (cj + coarse_count_[1] * static_cast<std::size_t>(ck))];
}

}  // namespace duplexfit::detail
