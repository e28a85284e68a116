// The disk-soup distance (see disk_distance.hpp).
#include "spatial/disk_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "duplexfit/neighbors.hpp"

namespace duplexfit::detail {

Eigen::VectorXd diskSoupDistance(const Points& queries, const Points& points, const Points& normals,
                                 const Eigen::VectorXd& areas, const NeighborIndex& index, int k) {
  Eigen::VectorXd out = Eigen::VectorXd::Constant(queries.rows(), std::numeric_limits<double>::infinity());
  if (points.rows() == 0 || queries.rows() == 0) return out;
  const NeighborLists nn = index.knnSearch(queries, std::min<int>(k, static_cast<int>(points.rows())));
#pragma omp parallel for schedule(static)
  for (Eigen::Index q = 0; q < queries.rows(); ++q) {
    const auto uq = static_cast<std::size_t>(q);
    double best = std::numeric_limits<double>::infinity();
    for (auto e = nn.offsets[uq]; e < nn.offsets[uq + 1]; ++e) {
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
