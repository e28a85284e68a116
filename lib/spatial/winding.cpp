// Fast generalized winding number of an oriented point cloud (see winding.hpp): an octree over the points,
// each node carrying the area-weighted centre p̃, the dipole d = Σ a_i n_i, the second moment
// C = Σ a_i n_i (p_i − p̃)ᵀ and its radius R. With x = p̃ − q and r = |x|, the far-field expansion of
// Σ a_i n_i·(p_i − q) / (4π|p_i − q|³) to second order is
//   w ≈ [ d·x / r³ + tr(C) / r³ − 3 xᵀ C x / r⁵ ] / (4π)
// (first-order Taylor expansion of the kernel's gradient about p̃). Nodes with r > β R use it.
#include "duplexfit/winding.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "spatial/morton.hpp"




namespace duplexfit {

namespace {

constexpr double kFourPi = 4.0 * 3.14159265358979323846;

struct Node {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d dipole = Eigen::Vector3d::Zero();
  Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
  double radius = 0.0;
  std::int32_t begin = 0, end = 0;  // range in the permuted point order
  std::int32_t child[8] = {-1, -1, -1, -1, -1, -1, -1, -1};
  bool leaf = true;
};

}  // namespace

Eigen::VectorXd estimatePointAreas(const Points& positions, const Points& normals, int k) {
  return estimatePointAreas(positions, normals, k, NeighborIndex(positions));
}

Eigen::VectorXd estimatePointAreas(const Points& positions, const Points& normals, int k, const NeighborIndex& index) {
  if (positions.rows() != normals.rows()) throw InvalidArgument("estimatePointAreas: positions and normals differ in count");
  if (k < 1) throw InvalidArgument("estimatePointAreas: k must be at least 1");
  if (index.size() != static_cast<std::size_t>(positions.rows())) {
    throw InvalidArgument("estimatePointAreas: the index holds " + std::to_string(index.size()) + " points, not " +
                          std::to_string(positions.rows()));
  }
  const Eigen::Index n = positions.rows();
  Eigen::VectorXd areas = Eigen::VectorXd::Zero(n);
  if (n < 2) return areas;
  const NeighborLists nn = index.knnSearch(positions, std::min<int>(k + 1, static_cast<int>(n)));
  // A fallback for points whose neighbours all disagree: the median area of the others.
  std::vector<char> known(static_cast<std::size_t>(n), 0);
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d ni = normals.row(i).transpose();
    if (ni.squaredNorm() == 0.0) continue;
    const Eigen::Vector3d u = ni.normalized();
    double rho2 = 0.0;
    int m = 0;
    const auto ui = static_cast<std::size_t>(i);
    for (auto e = nn.offsets[ui]; e < nn.offsets[ui + 1]; ++e) {
      const Index j = nn.indices[static_cast<std::size_t>(e)];
      if (j == i || normals.row(j).dot(normals.row(i)) <= 0.0) continue;
      Eigen::Vector3d v = (positions.row(j) - positions.row(i)).transpose();
      v -= v.dot(u) * u;
      rho2 = std::max(rho2, v.squaredNorm());
      ++m;
    }
    if (m > 0 && rho2 > 0.0) {
      areas[i] = 3.14159265358979323846 * rho2 / m;
      known[ui] = 1;
    }
  }
  std::vector<double> good;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (known[static_cast<std::size_t>(i)] != 0) good.push_back(areas[i]);
  }
  if (!good.empty()) {
    std::nth_element(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(good.size() / 2), good.end());
    const double median = good[good.size() / 2];
    for (Eigen::Index i = 0; i < n; ++i) {
      if (known[static_cast<std::size_t>(i)] == 0 && normals.row(i).squaredNorm() > 0.0) areas[i] = median;
    }
  }
  return areas;
}

struct WindingNumber::Impl {
  Points p, nrm;           // permuted into tree order
  Eigen::VectorXd a;       // areas, tree order
  Eigen::VectorXd areasInput;  // areas, input order
  std::vector<Node> nodes;
  WindingOptions opt;

  void build(const Points& positions, const Points& normals, const Eigen::VectorXd& areas) {
    const Eigen::Index n = positions.rows();
    std::vector<std::int32_t> order(static_cast<std::size_t>(n));
    std::iota(order.begin(), order.end(), 0);
    nodes.clear();
    nodes.reserve(static_cast<std::size_t>(2 * n / std::max(1, opt.leafSize) + 8));
    if (n > 0) {
      const Eigen::Vector3d lo = positions.colwise().minCoeff().transpose();
      const Eigen::Vector3d hi = positions.colwise().maxCoeff().transpose();
      const Eigen::Vector3d mid = 0.5 * (lo + hi);
      const double half = 0.5 * (hi - lo).maxCoeff() * (1.0 + 1e-9) + 1e-300;
      split(positions, order, 0, static_cast<std::int32_t>(n), mid, half, 0);
    }
    p.resize(n, 3);
    nrm.resize(n, 3);
    a.resize(n);
    for (Eigen::Index k = 0; k < n; ++k) {
      const auto i = order[static_cast<std::size_t>(k)];
      p.row(k) = positions.row(i);
      nrm.row(k) = normals.row(i);
      a[k] = areas[i];
    }
    // Moments bottom-up (children have larger indices than their parent).
    for (std::size_t t = nodes.size(); t-- > 0;) {
      Node& nd = nodes[t];
      double area = 0.0;
      Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
      for (std::int32_t k = nd.begin; k < nd.end; ++k) {
        area += a[k];
        weighted += a[k] * p.row(k).transpose();
      }
      nd.centre = area > 0.0 ? Eigen::Vector3d(weighted / area) : Eigen::Vector3d(p.row(nd.begin).transpose());
      nd.dipole.setZero();
      nd.moment.setZero();
      nd.radius = 0.0;
      for (std::int32_t k = nd.begin; k < nd.end; ++k) {
        const Eigen::Vector3d rel = p.row(k).transpose() - nd.centre;
        nd.dipole += a[k] * nrm.row(k).transpose();
        nd.moment += a[k] * nrm.row(k).transpose() * rel.transpose();
        nd.radius = std::max(nd.radius, rel.norm());
      }
    }
  }

  // Node over order[begin, end) inside the cube mid ± half; children split at the cube's centre.
  std::int32_t split(const Points& pts, std::vector<std::int32_t>& order, std::int32_t begin, std::int32_t end,
                     const Eigen::Vector3d& mid, double half, int depth) {
    const auto id = static_cast<std::int32_t>(nodes.size());
    nodes.emplace_back();
    nodes.back().begin = begin;
    nodes.back().end = end;
    if (end - begin <= opt.leafSize || depth >= 40) return id;
    auto octant = [&](std::int32_t i) {
      return (pts(i, 0) >= mid.x() ? 1 : 0) | (pts(i, 1) >= mid.y() ? 2 : 0) | (pts(i, 2) >= mid.z() ? 4 : 0);
    };
    std::int32_t count[9] = {0};
    for (std::int32_t k = begin; k < end; ++k) ++count[octant(order[static_cast<std::size_t>(k)]) + 1];
    for (int o = 0; o < 8; ++o) count[o + 1] += count[o];
    std::vector<std::int32_t> tmp(static_cast<std::size_t>(end - begin));
    std::int32_t pos[8];
    for (int o = 0; o < 8; ++o) pos[o] = count[o];
    for (std::int32_t k = begin; k < end; ++k) {
      const std::int32_t i = order[static_cast<std::size_t>(k)];
      tmp[static_cast<std::size_t>(pos[octant(i)]++)] = i;
    }
    std::copy(tmp.begin(), tmp.end(), order.begin() + begin);
    nodes[static_cast<std::size_t>(id)].leaf = false;
    for (int o = 0; o < 8; ++o) {
      if (count[o + 1] == count[o]) continue;
      Eigen::Vector3d cmid;
      for (int ax = 0; ax < 3; ++ax) cmid[ax] = mid[ax] + (((o >> ax) & 1) != 0 ? 0.5 : -0.5) * half;
      const std::int32_t c = split(pts, order, begin + count[o], begin + count[o + 1], cmid, 0.5 * half, depth + 1);
      nodes[static_cast<std::size_t>(id)].child[o] = c;
    }
    return id;
  }

  double direct(const Eigen::Vector3d& q, std::int32_t begin, std::int32_t end) const {
    double w = 0.0;
    for (std::int32_t k = begin; k < end; ++k) {
      const Eigen::Vector3d x = p.row(k).transpose() - q;
      const double r2 = x.squaredNorm();
      if (r2 == 0.0) continue;
      w += a[k] * x.dot(nrm.row(k).transpose()) / (r2 * std::sqrt(r2));
    }
    return w;
  }

  double at(const Eigen::Vector3d& q, double beta) const {
    if (nodes.empty()) return 0.0;
    double w = 0.0;
    std::int32_t stack[512];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& nd = nodes[static_cast<std::size_t>(stack[--top])];
      const Eigen::Vector3d x = nd.centre - q;
      const double r = x.norm();
      if (r > beta * nd.radius && r > 0.0) {
        const double r3 = r * r * r;
        w += nd.dipole.dot(x) / r3 + nd.moment.trace() / r3 - 3.0 * x.dot(nd.moment * x) / (r3 * r * r);
      } else if (nd.leaf || top + 8 > 512) {
        w += direct(q, nd.begin, nd.end);
      } else {
        for (const std::int32_t c : nd.child) {
          if (c >= 0) stack[top++] = c;
        }
      }
    }
    return w / kFourPi;
  }
};

WindingNumber::WindingNumber(const Points& positions, const Points& outwardNormals, const WindingOptions& options)
    : WindingNumber(positions, outwardNormals, estimatePointAreas(positions, outwardNormals, options.areaNeighbors),
                    options) {}

WindingNumber::WindingNumber(const Points& positions, const Points& outwardNormals, const Eigen::VectorXd& areas,
                             const WindingOptions& options)
    : impl_(std::make_unique<Impl>()) {
  if (positions.rows() != outwardNormals.rows() || positions.rows() != areas.size()) {
    throw InvalidArgument("WindingNumber: positions, normals and areas differ in count");
  }
  if (!(options.beta > 0.0) || options.leafSize < 1) throw InvalidArgument("WindingNumber: beta > 0 and leafSize >= 1");
  impl_->opt = options;
  impl_->areasInput = areas;
  impl_->build(positions, outwardNormals, areas);
}

WindingNumber::WindingNumber(WindingNumber&&) noexcept = default;
WindingNumber& WindingNumber::operator=(WindingNumber&&) noexcept = default;
WindingNumber::~WindingNumber() = default;

const Eigen::VectorXd& WindingNumber::areas() const noexcept { return impl_->areasInput; }

Eigen::VectorXd WindingNumber::evaluate(const Points& queries) const { return evaluate(queries, impl_->opt.beta); }

Eigen::VectorXd WindingNumber::evaluate(const Points& queries, double beta) const {
  if (!(beta > 0.0) || !std::isfinite(beta)) throw InvalidArgument("WindingNumber::evaluate: beta must be positive and finite");
  Eigen::VectorXd out(queries.rows());
  // In Morton order, so that consecutive queries walk the same nodes (each value is its own query's, so
  // the order changes no result).
  const std::vector<std::uint32_t> order = detail::processingOrder(queries, 4096);
  const auto n = static_cast<std::int64_t>(queries.rows());
#pragma omp parallel for schedule(dynamic, 64)
  for (std::int64_t s = 0; s < n; ++s) {
    const auto i = static_cast<Eigen::Index>(order.empty() ? s : static_cast<std::int64_t>(order[static_cast<std::size_t>(s)]));
    out[i] = impl_->at(queries.row(i).transpose(), beta);
  }
  return out;
}

Eigen::VectorXd WindingNumber::exact(const Points& queries) const {
  Eigen::VectorXd out(queries.rows());
  const auto n = static_cast<std::int32_t>(impl_->p.rows());
#pragma omp parallel for schedule(dynamic, 16)
  for (Eigen::Index i = 0; i < queries.rows(); ++i) out[i] = impl_->direct(queries.row(i).transpose(), 0, n) / kFourPi;
  return out;
}

}  // namespace duplexfit
