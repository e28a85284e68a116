// estimateNoise: how far a cloud's points scatter off their local planes, in point spacings (preprocess.hpp).
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/preprocess.hpp"

namespace duplexfit {

namespace {

double median(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

NoiseEstimate estimateNoise(const Points& positions, const NoiseOptions& options) {
  if (options.samples == 0 || options.neighbours < 4 || !(options.threshold > 0.0) || !std::isfinite(options.threshold)) {
    throw InvalidArgument("estimateNoise: samples must be positive, neighbours at least 4 and the threshold positive "
                          "(got " + std::to_string(options.samples) + ", " + std::to_string(options.neighbours) + ", " +
                          std::to_string(options.threshold) + ")");
  }
  NoiseEstimate out;
  out.threshold = options.threshold;
  const Eigen::Index n = positions.rows();
  const auto k = static_cast<Eigen::Index>(options.neighbours);
  if (n < k) return out;
  const Eigen::Index count = std::min<Eigen::Index>(n, static_cast<Eigen::Index>(options.samples));
  Points queries(count, 3);
  for (Eigen::Index s = 0; s < count; ++s) queries.row(s) = positions.row(s * n / count);
  const NeighborIndex index(positions);
  const NeighborLists near = index.knnSearch(queries, options.neighbours);
  // Each sample's nearest other point: the second hit (the first is the sample itself, or a point coinciding
  // with it at distance 0, which the spacing's median then ignores as one of many).
  std::vector<double> spacing, residual;
  spacing.reserve(static_cast<std::size_t>(count));
  residual.reserve(static_cast<std::size_t>(count));
  for (Eigen::Index s = 0; s < count; ++s) {
    const auto q = static_cast<std::size_t>(s);
    if (near.count(q) != static_cast<std::size_t>(k)) continue;
    const auto first = static_cast<std::size_t>(near.offsets[q]);
    spacing.push_back(near.distances[first + 1]);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (Eigen::Index j = 0; j < k; ++j) mean += positions.row(near.indices[first + static_cast<std::size_t>(j)]).transpose();
    mean /= static_cast<double>(k);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (Eigen::Index j = 0; j < k; ++j) {
      const Eigen::Vector3d d = positions.row(near.indices[first + static_cast<std::size_t>(j)]).transpose() - mean;
      cov += d * d.transpose();
    }
    cov /= static_cast<double>(k);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov, Eigen::EigenvaluesOnly);
    residual.push_back(std::sqrt(std::max(0.0, eig.eigenvalues()(0))));
  }
  if (spacing.empty()) return out;
  out.spacing = median(spacing);
  if (!(out.spacing > 0.0)) return out;
  for (double& r : residual) r /= out.spacing;
  out.ratio = median(residual);
  out.samples = residual.size();
  return out;
}

}  // namespace duplexfit
