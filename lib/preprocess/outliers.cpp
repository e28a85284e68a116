// Outliers (docs/method.md §9, "Outliers"). Far ones: points beyond a robust bounding box of the cloud. O(n):
// per axis the 0.5% and 99.5% quantiles give the box of the bulk, and a point more than `margin` box sizes
// outside it on any axis is an outlier. One stray point at x = 1e4 beside a unit sphere (sphere_180 in
// the reliability issue) otherwise sets the fit's bounding box, its σ_1 and its normalisation, and the
// sphere is lost. Isolated ones (specks inside the box, which would grow blobs of their own): the distance
// to the k-th nearest neighbour against the cloud's median of it (statistical outlier removal).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/preprocess.hpp"

namespace duplexfit {

OutlierReport findOutliers(const Points& positions, const OutlierOptions& options, const NeighborIndex* index) {
  if (!(options.quantile > 0.0 && options.quantile < 0.25)) {
    throw InvalidArgument("findOutliers: quantile must be in (0, 0.25)");
  }
  if (!(options.margin > 0.0) || !std::isfinite(options.margin)) throw InvalidArgument("findOutliers: margin must be positive");
  if (options.isolationFactor != 0.0 && (!(options.isolationFactor > 1.0) || !std::isfinite(options.isolationFactor))) {
    throw InvalidArgument("findOutliers: isolationFactor must be 0 (off) or above 1");
  }
  if (options.isolationFactor != 0.0 && (options.neighbours < 1 || options.neighbours > 256)) {
    throw InvalidArgument("findOutliers: neighbours must be in [1, 256]");
  }
  OutlierReport r;
  r.quantile = options.quantile;
  r.margin = options.margin;
  r.neighbours = options.isolationFactor != 0.0 ? options.neighbours : 0;
  r.isolationFactor = options.isolationFactor;
  const auto n = static_cast<std::size_t>(positions.rows());
  if (n < 20) return r;  // too few points for quantiles to mean anything
  Eigen::Vector3d lo, hi;
  std::vector<double> column(n);
  const auto at = [n](double q) { return static_cast<std::ptrdiff_t>(std::floor(q * static_cast<double>(n - 1))); };
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < n; ++i) column[i] = positions(static_cast<Eigen::Index>(i), a);
    std::nth_element(column.begin(), column.begin() + at(options.quantile), column.end());
    lo[a] = column[static_cast<std::size_t>(at(options.quantile))];
    std::nth_element(column.begin(), column.begin() + at(1.0 - options.quantile), column.end());
    hi[a] = column[static_cast<std::size_t>(at(1.0 - options.quantile))];
  }
  const double size = (hi - lo).maxCoeff();
  r.bulkMin = lo;
  r.bulkMax = hi;
  if (!(size > 0.0)) return r;
  const double slack = options.margin * size;
  for (std::size_t i = 0; i < n; ++i) {
    const auto row = static_cast<Eigen::Index>(i);
    double beyond = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double x = positions(row, a);
      beyond = std::max({beyond, lo[a] - x, x - hi[a]});
    }
    if (beyond > slack) {
      r.indices.push_back(static_cast<Index>(i));
      if (beyond > r.worstDistance) {
        r.worstDistance = beyond;
        r.worst = static_cast<Index>(i);
      }
    }
  }
  r.outsideBox = r.indices.size();
  const auto k = static_cast<std::size_t>(options.neighbours);
  if (options.isolationFactor == 0.0 || n <= 2 * k) return r;
  // The k-th neighbour distance of every point (the query itself is its own first neighbour).
  if (index != nullptr && index->size() != n) {
    throw InvalidArgument("findOutliers: the index holds " + std::to_string(index->size()) + " points, the cloud " +
                          std::to_string(n));
  }
  std::optional<NeighborIndex> own;
  if (index == nullptr) index = &own.emplace(positions);
  const NeighborLists knn = index->knnSearch(positions, static_cast<int>(k + 1));
  std::vector<double> dk(n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t begin = knn.offsets[i], end = knn.offsets[i + 1];
    if (end > begin) dk[i] = knn.distances[static_cast<std::size_t>(end - 1)];
  }
  std::vector<double> sorted = dk;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(n / 2), sorted.end());
  const double median = sorted[n / 2];
  r.medianNeighbourDistance = median;
  if (!(median > 0.0)) return r;  // duplicates everywhere: nothing to compare with
  std::vector<char> flagged(n, 0);
  for (const Index i : r.indices) flagged[static_cast<std::size_t>(i)] = 1;
  for (std::size_t i = 0; i < n; ++i) {
    const double ratio = dk[i] / median;
    if (flagged[i] || !(ratio > options.isolationFactor)) continue;
    flagged[i] = 1;
    ++r.isolated;
    if (ratio > r.worstIsolation) {
      r.worstIsolation = ratio;
      r.mostIsolated = static_cast<Index>(i);
    }
  }
  r.indices.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (flagged[i]) r.indices.push_back(static_cast<Index>(i));
  }
  return r;
}

std::string OutlierReport::describe(const Points& positions) const {
  if (indices.empty()) return "no outliers";
  std::ostringstream s;
  if (outsideBox > 0) {
    const auto w = static_cast<Eigen::Index>(worst);
    s << outsideBox << " point" << (outsideBox == 1 ? "" : "s") << " far outside the rest of the cloud (worst: point "
      << worst << " at (" << positions(w, 0) << ", " << positions(w, 1) << ", " << positions(w, 2) << "), "
      << worstDistance << " beyond the box of the other points [" << bulkMin.x() << ", " << bulkMin.y() << ", "
      << bulkMin.z() << "] - [" << bulkMax.x() << ", " << bulkMax.y() << ", " << bulkMax.z() << "])";
  }
  if (isolated > 0) {
    const auto w = static_cast<Eigen::Index>(mostIsolated);
    s << (outsideBox > 0 ? "; " : "") << isolated << " point" << (isolated == 1 ? "" : "s")
      << " isolated from the rest (worst: point " << mostIsolated << " at (" << positions(w, 0) << ", "
      << positions(w, 1) << ", " << positions(w, 2) << "), its neighbours " << worstIsolation
      << "x farther than the cloud's median of " << medianNeighbourDistance << ")";
  }
  return s.str();
}

}  // namespace duplexfit
