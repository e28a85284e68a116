// The disk-soup distance (see disk_distance.hpp).
#include "spatial/disk_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"

namespace duplexfit::detail {

Eigen::VectorXd diskSoupDistance(const Points& queries, const Points& points, const Points& normals,
                                 const Eigen::VectorXd& areas, const NeighborIndex& index, int k) {
  Eigen::VectorXd out = Eigen::VectorXd::Constant(queries.rows(), std::numeric_limits<double>::infinity());
  if (points.rows() == 0 || queries.rows() == 0) return out;
  return diskSoupDistance(queries, points, normals, areas,
                          index.knnSearch(queries, std::min<int>(k, static_cast<int>(points.rows()))), k);
}

Eigen::VectorXd diskSoupDistance(const Points& queries, const Points& points, const Points& normals,
                                 const Eigen::VectorXd& areas, const NeighborLists& nn, int k) {
  Eigen::VectorXd out = Eigen::VectorXd::Constant(queries.rows(), std::numeric_limits<double>::infinity());
  if (points.rows() == 0 || queries.rows() == 0) return out;
  if (nn.queries() != static_cast<std::size_t>(queries.rows()) || k < 1) {
    throw InvalidArgument("diskSoupDistance: " + std::to_string(nn.queries()) + " neighbour lists for " +
                          std::to_string(queries.rows()) + " queries, k = " + std::to_string(k));
  }
#pragma omp parallel for schedule(static)
  for (Eigen::Index q = 0; q < queries.rows(); ++q) {
    const auto uq = static_cast<std::size_t>(q);
    double best = std::numeric_limits<double>::infinity();
    const auto end = std::min(nn.offsets[uq + 1], nn.offsets[uq] + k);
    for (auto e = nn.offsets[uq]; e < end; ++e) {
      const Index i = nn.indices[static_cast<std::size_t>(e)];
      const Eigen::Vector3d v = (queries.row(q) - points.row(i)).transpose();
      const Eigen::Vector3d n = normals.row(i).transpose();
      double d = v.norm();
      if (n.squaredNorm() > 0.0) {
        const double h = v.dot(n) / n.norm();
        const double t = std::sqrt(std::max(0.0, v.squaredNorm() - h * h));
        const double r = std::sqrt(std::max(0.0, areas[i]) / 3.14159265358979323846);
        d = std::hypot(h, std::max(0.0, t - r));
      }
      best = std::min(best, d);
    }
    out[q] = best;
  }
  return out;
}

}  // namespace duplexfit::detail
