// Hierarchy construction (docs/method.md §4): box, adaptive-octree σ_0, M, and per-level centroids.
#include "fit/hierarchy.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

namespace duplexfit::detail {

HierarchyBox hierarchyBox(const Points& points) {
  HierarchyBox box;
  if (points.rows() == 0) return box;
  Eigen::Vector3d lo = points.colwise().minCoeff().transpose();
  Eigen::Vector3d hi = points.colwise().maxCoeff().transpose();
  double diag = (hi - lo).norm();
  if (diag == 0.0) diag = 1.0;  // all coincident: callers reject this earlier (checkFittable)
  for (int i = 0; i < 3; ++i) {
    if (hi[i] - lo[i] < 1e-3 * diag) {
      const double mid = 0.5 * (hi[i] + lo[i]);
      lo[i] = mid - 0.5e-3 * diag;
      hi[i] = mid + 0.5e-3 * diag;
    }
  }
  const double pad = 1e-9 * (hi - lo).norm();
  box.min = lo.array() - pad;
  box.max = hi.array() + pad;
  box.diagonal = (box.max - box.min).norm();
  return box;
}

namespace {

struct OctreeStats {
  double diagonalSum = 0.0;
  std::size_t leaves = 0;
};

void splitCell(const Points& p, std::vector<std::int32_t>& idx, std::size_t begin, std::size_t end,
               const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int depth, int maxPerLeaf, OctreeStats& s) {
  if (end == begin) return;
  if (static_cast<int>(end - begin) <= maxPerLeaf || depth >= 21) {
    s.diagonalSum += (hi - lo).norm();
    ++s.leaves;
    return;
  }
  const Eigen::Vector3d mid = 0.5 * (lo + hi);
  auto octant = [&](std::int32_t i) {
    return (p(i, 0) >= mid.x() ? 1 : 0) | (p(i, 1) >= mid.y() ? 2 : 0) | (p(i, 2) >= mid.z() ? 4 : 0);
  };
  // Counting sort of the range by octant.
  std::size_t count[9] = {0};
  for (std::size_t k = begin; k < end; ++k) ++count[octant(idx[k]) + 1];
  for (int o = 0; o < 8; ++o) count[o + 1] += count[o];
  std::vector<std::int32_t> tmp(end - begin);
  std::size_t pos[8];
  for (int o = 0; o < 8; ++o) pos[o] = count[o];
  for (std::size_t k = begin; k < end; ++k) tmp[pos[octant(idx[k])]++] = idx[k];
  std::copy(tmp.begin(), tmp.end(), idx.begin() + static_cast<std::ptrdiff_t>(begin));
  for (int o = 0; o < 8; ++o) {
    Eigen::Vector3d clo, chi;
    for (int a = 0; a < 3; ++a) {
      const bool upper = ((o >> a) & 1) != 0;
      clo[a] = upper ? mid[a] : lo[a];
      chi[a] = upper ? hi[a] : mid[a];
    }
    splitCell(p, idx, begin + count[o], begin + count[o + 1], clo, chi, depth + 1, maxPerLeaf, s);
  }
}

}  // namespace

double adaptiveSigma0(const Points& points, const HierarchyBox& box, int maxPerLeaf) {
  std::vector<std::int32_t> idx(static_cast<std::size_t>(points.rows()));
  std::iota(idx.begin(), idx.end(), 0);
  OctreeStats s;
  splitCell(points, idx, 0, idx.size(), box.min, box.max, 0, maxPerLeaf, s);
  return s.leaves == 0 ? 0.75 * box.diagonal : 0.75 * s.diagonalSum / static_cast<double>(s.leaves);
}

void adaptiveOctreeSums(const Points& points, const HierarchyBox& box, double& diagonalSum, std::size_t& leaves,
                        int maxPerLeaf) {
  std::vector<std::int32_t> idx(static_cast<std::size_t>(points.rows()));
  std::iota(idx.begin(), idx.end(), 0);
  OctreeStats s;
  splitCell(points, idx, 0, idx.size(), box.min, box.max, 0, maxPerLeaf, s);
  diagonalSum = s.diagonalSum;
  leaves = s.leaves;
}

int levelCount(double sigma1, double sigma0) {
  return std::max(1, static_cast<int>(std::ceil(std::log2(2.0 * sigma1 / sigma0) - 1e-12)));
}

LevelPoints cellCentroids(const Points& points, const Points& normals, const HierarchyBox& box, int depth) {
  const auto n = static_cast<std::size_t>(points.rows());
  const std::uint64_t cells = std::uint64_t{1} << depth;
  const Eigen::Vector3d extent = box.max - box.min;
  std::vector<std::pair<std::uint64_t, std::int32_t>> keyed(n);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n); ++i) {
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
      const double t = (points(i, a) - box.min[a]) / extent[a] * static_cast<double>(cells);
      const auto c = std::min<std::uint64_t>(cells - 1, static_cast<std::uint64_t>(std::max(0.0, t)));
      key = (key << 21) | c;
    }
    keyed[static_cast<std::size_t>(i)] = {key, static_cast<std::int32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  std::size_t groups = 0;
  for (std::size_t k = 0; k < n; ++k) groups += (k == 0 || keyed[k].first != keyed[k - 1].first) ? 1 : 0;
  LevelPoints out;
  out.positions.resize(static_cast<Eigen::Index>(groups), 3);
  out.normals.resize(static_cast<Eigen::Index>(groups), 3);
  Eigen::Index g = -1;
  std::size_t count = 0;
  Eigen::Vector3d sumP = Eigen::Vector3d::Zero(), sumN = Eigen::Vector3d::Zero();
  auto flush = [&]() {
    if (count == 0) return;
    out.positions.row(g) = (sumP / static_cast<double>(count)).transpose();
    const double len = sumN.norm();
    if (len > 1e-6 * static_cast<double>(count)) {
      out.normals.row(g) = (sumN / len).transpose();
    } else {
      out.normals.row(g).setZero();
    }
  };
  for (std::size_t k = 0; k < n; ++k) {
    if (k == 0 || keyed[k].first != keyed[k - 1].first) {
      flush();
      ++g;
      count = 0;
      sumP.setZero();
      sumN.setZero();
    }
    const std::int32_t i = keyed[k].second;
    sumP += points.row(i).transpose();
    sumN += normals.row(i).transpose();
    ++count;
  }
  flush();
  return out;
}

}  // namespace duplexfit::detail
