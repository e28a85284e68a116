// Morton-range partition, row redistribution, halo exchange and gathered cell centroids of the
// distributed fit (docs/method.md, "Distributed fit").
#include "fit/partition.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_set>
#include <utility>

#include "duplexfit/error.hpp"

namespace duplexfit::detail {

namespace {

std::uint64_t spread3(std::uint64_t v) {
  v &= 0x1fffffULL;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

std::uint64_t cellOf(double x, double lo, double extent, std::uint64_t cells) {
  const double t = (x - lo) / extent * static_cast<double>(cells);
  return std::min<std::uint64_t>(cells - 1, static_cast<std::uint64_t>(std::max(0.0, t)));
}

// Rows packed as id, position, normal (7 values of 8 bytes).
constexpr std::size_t kRowBytes = 7 * 8;

void packRow(std::vector<unsigned char>& out, std::int64_t id, const Points& p, const Points& n, Eigen::Index i) {
  double v[6] = {p(i, 0), p(i, 1), p(i, 2), n(i, 0), n(i, 1), n(i, 2)};
  const std::size_t at = out.size();
  out.resize(at + kRowBytes);
  std::memcpy(out.data() + at, &id, 8);
  std::memcpy(out.data() + at + 8, v, 48);
}

OwnedRows unpackRows(const std::vector<unsigned char>& bytes) {
  OwnedRows out;
  const auto n = static_cast<Eigen::Index>(bytes.size() / kRowBytes);
  out.positions.resize(n, 3);
  out.normals.resize(n, 3);
  out.ids.resize(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    const unsigned char* at = bytes.data() + static_cast<std::size_t>(i) * kRowBytes;
    double v[6];
    std::memcpy(&out.ids[static_cast<std::size_t>(i)], at, 8);
    std::memcpy(v, at + 8, 48);
    for (int a = 0; a < 3; ++a) {
      out.positions(i, a) = v[a];
      out.normals(i, a) = v[3 + a];
    }
  }
  return out;
}

}  // namespace

std::uint64_t mortonKey63(const Eigen::Vector3d& p, const HierarchyBox& box) noexcept {
  constexpr std::uint64_t cells = std::uint64_t{1} << 21;
  std::uint64_t key = 0;
  for (int a = 0; a < 3; ++a) {
    const double extent = box.max[a] - box.min[a];
    const std::uint64_t c = extent > 0.0 ? cellOf(p[a], box.min[a], extent, cells) : 0;
    key |= spread3(c) << a;
  }
  return key;
}

std::vector<Eigen::Index> mortonOrder(const Points& positions, const HierarchyBox& box) {
  std::vector<std::pair<std::uint64_t, Eigen::Index>> keyed(static_cast<std::size_t>(positions.rows()));
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    keyed[static_cast<std::size_t>(i)] = {mortonKey63(positions.row(i).transpose(), box), i};
  }
  std::sort(keyed.begin(), keyed.end());  // (key, row): ties in row order
  std::vector<Eigen::Index> order(keyed.size());
  for (std::size_t r = 0; r < keyed.size(); ++r) order[r] = keyed[r].second;
  return order;
}

std::vector<std::uint64_t> balancedSplitters(Communicator& comm, const std::vector<std::uint64_t>& keys,
                                             int histogramBits, int parts) {
  if (histogramBits < 1 || histogramBits > 24) throw InvalidArgument("balancedSplitters: histogramBits must be in [1, 24]");
  if (parts < 0) throw InvalidArgument("balancedSplitters: parts must be >= 0");
  const int shift = 63 - histogramBits;
  const std::size_t buckets = std::size_t{1} << histogramBits;
  std::vector<std::int64_t> histogram(buckets, 0);
  for (const std::uint64_t k : keys) ++histogram[static_cast<std::size_t>(k >> shift)];
  comm.allreduce(histogram.data(), histogram.size(), ReduceOp::Sum);
  std::int64_t total = 0;
  for (const std::int64_t h : histogram) total += h;
  const int p = std::max(1, parts > 0 ? parts : comm.size());
  std::vector<std::uint64_t> splitters(static_cast<std::size_t>(p) + 1, std::uint64_t{1} << 63);
  splitters[0] = 0;
  std::int64_t cumulative = 0;
  std::size_t b = 0;
  for (int r = 1; r < p; ++r) {
    const double target = static_cast<double>(total) * r / p;
    // The bucket boundary nearest the target: advance while the next bucket brings the count closer.
    while (b < buckets && std::abs(static_cast<double>(cumulative + histogram[b]) - target) <=
                              std::abs(static_cast<double>(cumulative) - target)) {
      cumulative += histogram[b];
      ++b;
    }
    splitters[static_cast<std::size_t>(r)] = static_cast<std::uint64_t>(b) << shift;
    if (b == buckets) splitters[static_cast<std::size_t>(r)] = std::uint64_t{1} << 63;
  }
  return splitters;
}

int ownerOfKey(const std::vector<std::uint64_t>& splitters, std::uint64_t key) noexcept {
  const auto it = std::upper_bound(splitters.begin() + 1, splitters.end() - 1, key);
  return static_cast<int>(it - splitters.begin()) - 1;
}

OwnedRows redistribute(Communicator& comm, const Points& positions, const Points& normals,
                       const std::vector<std::int64_t>& ids, const std::vector<std::uint64_t>& keys,
                       const std::vector<std::uint64_t>& splitters) {
  if (comm.size() == 1) {
    // One rank owns every row, in its order: what packing, the exchange and unpacking would return
    // (20M rows: 9 s saved).
    return OwnedRows{positions, normals, ids};
  }
  std::vector<std::vector<unsigned char>> send(static_cast<std::size_t>(comm.size()));
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    const auto to = static_cast<std::size_t>(ownerOfKey(splitters, keys[static_cast<std::size_t>(i)]));
    packRow(send[to], ids[static_cast<std::size_t>(i)], positions, normals, i);
  }
  std::vector<std::size_t> counts;
  return unpackRows(comm.alltoallv(send, counts));
}

int firstBlockOfRank(int rank, int ranks, int blocks) noexcept {
  return static_cast<int>(static_cast<std::int64_t>(rank) * blocks / std::max(1, ranks));
}

namespace {

// The halo's grid: cubic cells of side h ≥ radius (at most 2^20 a side), keyed with a one-cell margin so
// that the neighbours of every cell have keys.
class HaloGrid {
 public:
  HaloGrid(const Points& positions, const HierarchyBox& box, double radius)
      : p_(positions), box_(box), h_(std::max(radius, (box.max - box.min).maxCoeff() / static_cast<double>(1 << 20))) {}
  std::uint64_t cell(Eigen::Index i, int dx = 0, int dy = 0, int dz = 0) const {
    const int d[3] = {dx, dy, dz};
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      const auto c = static_cast<std::int64_t>(std::floor((p_(i, a) - box_.min[a]) / h_)) + d[a] + 1;
      key = (key << 21) | static_cast<std::uint64_t>(std::clamp<std::int64_t>(c, 0, (1 << 21) - 1));
    }
    return key;
  }
  /// Whether row i lies in one of `cells` or next to one.
  template <class Set>
  bool near(Eigen::Index i, const Set& cells) const {
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          if (cells.count(cell(i, dx, dy, dz)) != 0) return true;
        }
      }
    }
    return false;
  }

 private:
  const Points& p_;
  const HierarchyBox& box_;
  double h_;
};

}  // namespace

std::vector<Eigen::Index> rowsNear(const Points& positions, const std::vector<char>& core, const HierarchyBox& box,
                                   double radius) {
  const HaloGrid grid(positions, box, radius);
  std::unordered_set<std::uint64_t> cells;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    if (core[static_cast<std::size_t>(i)] != 0) cells.insert(grid.cell(i));
  }
  std::vector<Eigen::Index> out;
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    if (core[static_cast<std::size_t>(i)] != 0 || grid.near(i, cells)) out.push_back(i);
  }
  return out;
}

OwnedRows exchangeHalo(Communicator& comm, const Points& positions, const Points& normals,
                       const std::vector<std::int64_t>& ids, const HierarchyBox& box, double radius) {
  const int p = comm.size();
  if (p == 1) return OwnedRows{Points(0, 3), Points(0, 3), {}};
  const HaloGrid grid(positions, box, radius);
  std::vector<std::uint64_t> occupied;
  occupied.reserve(static_cast<std::size_t>(positions.rows()));
  for (Eigen::Index i = 0; i < positions.rows(); ++i) occupied.push_back(grid.cell(i));
  std::sort(occupied.begin(), occupied.end());
  occupied.erase(std::unique(occupied.begin(), occupied.end()), occupied.end());
  std::vector<std::size_t> counts;
  const std::vector<std::uint64_t> all = comm.allgather(occupied, &counts);
  std::vector<std::vector<unsigned char>> send(static_cast<std::size_t>(p));
  std::size_t begin = 0;
  for (int r = 0; r < p; ++r) {
    const std::size_t end = begin + counts[static_cast<std::size_t>(r)];
    if (r != comm.rank()) {
      const std::unordered_set<std::uint64_t> theirs(all.begin() + static_cast<std::ptrdiff_t>(begin),
                                                     all.begin() + static_cast<std::ptrdiff_t>(end));
      for (Eigen::Index i = 0; i < positions.rows(); ++i) {
        if (grid.near(i, theirs)) packRow(send[static_cast<std::size_t>(r)], ids[static_cast<std::size_t>(i)], positions, normals, i);
      }
    }
    begin = end;
  }
  std::vector<std::size_t> received;
  return unpackRows(comm.alltoallv(send, received));
}

std::vector<CellSum> cellSums(const Points& points, const Points& normals, const HierarchyBox& box, int depth) {
  const auto n = static_cast<std::size_t>(points.rows());
  const std::uint64_t cells = std::uint64_t{1} << depth;
  const Eigen::Vector3d extent = box.max - box.min;
  std::vector<std::pair<std::uint64_t, std::int32_t>> keyed(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      // The same cell as cellCentroids (hierarchy.cpp), so that one rank reproduces it exactly.
      const double t = (points(static_cast<Eigen::Index>(i), a) - box.min[a]) / extent[a] * static_cast<double>(cells);
      const auto c = std::min<std::uint64_t>(cells - 1, static_cast<std::uint64_t>(std::max(0.0, t)));
      key = (key << 21) | c;
    }
    keyed[i] = {key, static_cast<std::int32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<CellSum> out;
  for (std::size_t k = 0; k < n; ++k) {
    if (k == 0 || keyed[k].first != keyed[k - 1].first) {
      out.emplace_back();
      out.back().key = keyed[k].first;
    }
    CellSum& s = out.back();
    const auto i = static_cast<Eigen::Index>(keyed[k].second);
    for (int a = 0; a < 3; ++a) {
      s.position[a] += points(i, a);
      s.normal[a] += normals(i, a);
    }
    s.count += 1.0;
  }
  return out;
}

LevelPoints gatheredCentroids(Communicator& comm, const Points& points, const Points& normals, const HierarchyBox& box,
                              int depth) {
  std::vector<CellSum> all = comm.allgather(cellSums(points, normals, box, depth));
  // Stable by key: a cell's partial sums are added in rank order, the same on every rank.
  std::stable_sort(all.begin(), all.end(), [](const CellSum& a, const CellSum& b) { return a.key < b.key; });
  std::vector<CellSum> merged;
  for (const CellSum& s : all) {
    if (merged.empty() || merged.back().key != s.key) {
      merged.push_back(s);
      continue;
    }
    CellSum& m = merged.back();
    m.count += s.count;
    for (int a = 0; a < 3; ++a) {
      m.position[a] += s.position[a];
      m.normal[a] += s.normal[a];
    }
  }
  LevelPoints out;
  out.positions.resize(static_cast<Eigen::Index>(merged.size()), 3);
  out.normals.resize(static_cast<Eigen::Index>(merged.size()), 3);
  for (std::size_t g = 0; g < merged.size(); ++g) {
    const CellSum& m = merged[g];
    const auto row = static_cast<Eigen::Index>(g);
    const Eigen::Vector3d sumP(m.position[0], m.position[1], m.position[2]);
    const Eigen::Vector3d sumN(m.normal[0], m.normal[1], m.normal[2]);
    out.positions.row(row) = (sumP / m.count).transpose();
    const double len = sumN.norm();
    if (len > 1e-6 * m.count) {
      out.normals.row(row) = (sumN / len).transpose();
    } else {
      out.normals.row(row).setZero();
    }
  }
  return out;
}

}  // namespace duplexfit::detail
