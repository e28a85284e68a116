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

NoiseEstimate estimateNoise(const Points& positions, const NeighborIndex& index, const NoiseOptions& options) {
  if (options.samples == 0 || options.neighbours < 4 || !(options.threshold > 0.0) || !std::isfinite(options.threshold)) {
    throw InvalidArgument("estimateNoise: samples must be positive, neighbours at least 4 and the threshold positive "
                          "(got " + std::to_string(options.samples) + ", " + std::to_string(options.neighbours) + ", " +
                          std::to_string(options.threshold) + ")");
  }
  NoiseEstimate out;
  out.threshold = options.threshold;
  const Eigen::Index n = positions.rows();
  const auto k = static_cast<Eigen::Index>(options.neighbours);
  if (index.size() != static_cast<std::size_t>(n)) {
    throw InvalidArgument("estimateNoise: the index holds " + std::to_string(index.size()) + " points, the cloud " +
                          std::to_string(n));
  }
  if (n < k) return out;
  const Eigen::Index count = std::min<Eigen::Index>(n, static_cast<Eigen::Index>(options.samples));
  // Each sample's neighbourhood: its k nearest distinct points (itself included). Coincident points (unmerged
  // duplicates) count once, so the few samples whose k hits repeat points are searched again with twice, four
  // and eight times k hits; the spacing is the nearest distinct point's distance.
  std::vector<double> spacing, residual;  // of the measured samples, in any order (only medians are taken)
  std::vector<Eigen::Index> pending(static_cast<std::size_t>(count));  // the samples' rows still to measure
  for (Eigen::Index s = 0; s < count; ++s) pending[static_cast<std::size_t>(s)] = s * n / count;
  std::vector<Eigen::Vector3d> distinct;
  for (Eigen::Index want = k; !pending.empty(); want *= 2) {
    const bool last = want >= 8 * k || want >= n;
    Points pq(static_cast<Eigen::Index>(pending.size()), 3);
    for (std::size_t r = 0; r < pending.size(); ++r) pq.row(static_cast<Eigen::Index>(r)) = positions.row(pending[r]);
    const NeighborLists near = index.knnSearch(pq, static_cast<int>(std::min(want, n)));
    std::vector<Eigen::Index> again;
    for (std::size_t r = 0; r < pending.size(); ++r) {
      distinct.clear();
      double h = 0.0;
      for (auto e = near.offsets[r]; e < near.offsets[r + 1] && static_cast<Eigen::Index>(distinct.size()) < k; ++e) {
        const Eigen::Vector3d x = positions.row(near.indices[static_cast<std::size_t>(e)]).transpose();
        if (std::find(distinct.begin(), distinct.end(), x) != distinct.end()) continue;
        if (!distinct.empty() && !(h > 0.0)) h = near.distances[static_cast<std::size_t>(e)];
        distinct.push_back(x);
      }
      if (static_cast<Eigen::Index>(distinct.size()) < k && !last) {
        again.push_back(pending[r]);
        continue;
      }
      if (distinct.size() < 4 || !(h > 0.0)) continue;  // not measured
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (const Eigen::Vector3d& x : distinct) mean += x;
      mean /= static_cast<double>(distinct.size());
      Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
      for (const Eigen::Vector3d& x : distinct) cov += (x - mean) * (x - mean).transpose();
      cov /= static_cast<double>(distinct.size());
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov, Eigen::EigenvaluesOnly);
      spacing.push_back(h);
      residual.push_back(std::sqrt(std::max(0.0, eig.eigenvalues()(0))));
    }
    pending.swap(again);
  }
  if (spacing.empty()) return out;
  out.spacing = median(spacing);
  if (!(out.spacing > 0.0)) return out;
  for (double& r : residual) r /= out.spacing;
  out.ratio = median(residual);
  out.samples = residual.size();
  return out;
}

NoiseEstimate estimateNoise(const Points& positions, const NoiseOptions& options) {
  const NeighborIndex index(positions);
  return estimateNoise(positions, index, options);
}

}  // namespace duplexfit
