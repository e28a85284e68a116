// PointSet: validation and normalisation of oriented point clouds, duplicate merging (a hash over
// rounded positions, docs/method.md §3.5) and the fittability checks run before a fit.
#include "duplexfit/point_set.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "duplexfit/error.hpp"

namespace duplexfit {

namespace {

/// Normals at most this long count as "no normal" (point_set.hpp).
constexpr double kZeroNormalLength = 1e-12;

/// Key of a (rounded) position: three 64-bit words, either bit patterns or cell indices.
struct PositionKey {
  std::uint64_t a, b, c;
  bool operator==(const PositionKey& o) const noexcept { return a == o.a && b == o.b && c == o.c; }
  bool operator<(const PositionKey& o) const noexcept {
    return a != o.a ? a < o.a : (b != o.b ? b < o.b : c < o.c);
  }
};

std::uint64_t bitsOf(double v) {
  if (v == 0.0) v = 0.0;  // −0 and +0 are the same position
  std::uint64_t bits = 0;
  std::memcpy(&bits, &v, sizeof bits);
  return bits;
}

std::string describePoint(const Points& p, Eigen::Index i) {
  return "(" + std::to_string(p(i, 0)) + ", " + std::to_string(p(i, 1)) + ", " +
         std::to_string(p(i, 2)) + ")";
}

std::string describeNumber(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

PointSet::PointSet(Points positions, Points normals)
    : positions_(std::move(positions)), normals_(std::move(normals)) {
  if (positions_.rows() != normals_.rows()) {
    throw InvalidArgument("PointSet: " + std::to_string(positions_.rows()) + " positions but " +
                          std::to_string(normals_.rows()) + " normals");
  }
  for (Eigen::Index i = 0; i < positions_.rows(); ++i) {
    if (!positions_.row(i).allFinite()) {
      throw InvalidArgument("PointSet: position of point " + std::to_string(i) + " is not finite");
    }
    if (!normals_.row(i).allFinite()) {
      throw InvalidArgument("PointSet: normal of point " + std::to_string(i) + " is not finite");
    }
    const double length = normals_.row(i).norm();
    if (length <= kZeroNormalLength) {
      normals_.row(i).setZero();
    } else {
      normals_.row(i) /= length;
    }
  }
}

PointSet PointSet::fromNormalized(Points positions, Points normals) {
  PointSet out;
  if (positions.rows() != normals.rows()) {
    throw InvalidArgument("PointSet: " + std::to_string(positions.rows()) + " positions but " +
                          std::to_string(normals.rows()) + " normals");
  }
  for (Eigen::Index i = 0; i < positions.rows(); ++i) {
    if (!positions.row(i).allFinite()) throw InvalidArgument("PointSet: position of point " + std::to_string(i) + " is not finite");
    if (!normals.row(i).allFinite()) throw InvalidArgument("PointSet: normal of point " + std::to_string(i) + " is not finite");
  }
  out.positions_ = std::move(positions);
  out.normals_ = std::move(normals);
  return out;
}

Eigen::AlignedBox3d PointSet::bounds() const {
  Eigen::AlignedBox3d box;  // default-constructed: empty
  for (Eigen::Index i = 0; i < positions_.rows(); ++i) {
    box.extend(Eigen::Vector3d(positions_.row(i).transpose()));
  }
  return box;
}

std::size_t PointSet::zeroNormals() const {
  std::size_t count = 0;
  for (Eigen::Index i = 0; i < normals_.rows(); ++i) {
    if (normals_(i, 0) == 0.0 && normals_(i, 1) == 0.0 && normals_(i, 2) == 0.0) ++count;
  }
  return count;
}

std::size_t PointSet::mergeDuplicates(double relativeTolerance) {
  if (!(relativeTolerance >= 0.0) || !std::isfinite(relativeTolerance)) {
    throw InvalidArgument("mergeDuplicates: relativeTolerance must be finite and >= 0, got " +
                          std::to_string(relativeTolerance));
  }
  const Eigen::Index n = positions_.rows();
  if (n < 2) return 0;

  // Rounding to cells of size h = tolerance·L, measured from the box minimum. When h is zero or so
  // small that cell indices would not fit in 53 bits, the comparison is exact (bit patterns).
  const Eigen::AlignedBox3d box = bounds();
  const double h = relativeTolerance * box.diagonal().norm();
  const double maxExtent = box.diagonal().maxCoeff();
  const bool exact = !(h > 0.0) || maxExtent / h > 4.0e15;
  auto keyOf = [&](Eigen::Index i) {
    if (exact) {
      return PositionKey{bitsOf(positions_(i, 0)), bitsOf(positions_(i, 1)),
                         bitsOf(positions_(i, 2))};
    }
    auto cell = [&](int axis) {
      const double c = std::round((positions_(i, axis) - box.min()(axis)) / h);
      return static_cast<std::uint64_t>(static_cast<std::int64_t>(c));
    };
    return PositionKey{cell(0), cell(1), cell(2)};
  };

  // Groups of equal keys by sorting (key, index): the hash map of the first version spent most of its time
  // allocating nodes and missing the cache (20M points: more than 20 s; sorting: a few). Each group is
  // numbered by the order of its first point, as a single pass in input order would number it.
  const auto un = static_cast<std::size_t>(n);
  std::vector<std::pair<PositionKey, Eigen::Index>> entries(un);
  for (Eigen::Index i = 0; i < n; ++i) entries[static_cast<std::size_t>(i)] = {keyOf(i), i};
  std::sort(entries.begin(), entries.end(), [](const auto& x, const auto& y) {
    return x.first < y.first || (x.first == y.first && x.second < y.second);
  });
  std::vector<Eigen::Index> firstOf(un);  // the first point of each point's group
  for (std::size_t run = 0; run < un;) {
    std::size_t end = run + 1;
    while (end < un && entries[end].first == entries[run].first) ++end;
    for (std::size_t k = run; k < end; ++k) firstOf[static_cast<std::size_t>(entries[k].second)] = entries[run].second;
    run = end;
  }
  decltype(entries)().swap(entries);
  std::vector<Eigen::Index> groupOf(un);
  std::vector<Eigen::Index> groupSize;
  Eigen::Index groups = 0;
  for (std::size_t i = 0; i < un; ++i) {
    if (firstOf[i] == static_cast<Eigen::Index>(i)) {
      groupOf[i] = groups++;
      groupSize.push_back(0);
    } else {
      groupOf[i] = groupOf[static_cast<std::size_t>(firstOf[i])];  // an earlier point: already numbered
    }
    ++groupSize[static_cast<std::size_t>(groupOf[i])];
  }
  if (groups == n) return 0;

  // Each group keeps its first point's position; normals are summed and renormalised, and become
  // zero when they cancel (‖Σν‖ ≤ 10⁻⁶·count, the zero test of docs/method.md §3.3).
  Points positions(groups, 3);
  Points normals = Points::Zero(groups, 3);
  std::vector<bool> seen(static_cast<std::size_t>(groups), false);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index g = groupOf[static_cast<std::size_t>(i)];
    if (!seen[static_cast<std::size_t>(g)]) {
      seen[static_cast<std::size_t>(g)] = true;
      positions.row(g) = positions_.row(i);
    }
    normals.row(g) += normals_.row(i);
  }
  for (Eigen::Index g = 0; g < groups; ++g) {
    const double count = static_cast<double>(groupSize[static_cast<std::size_t>(g)]);
    const double length = normals.row(g).norm();
    if (count > 1.0 && length <= 1e-6 * count) {
      normals.row(g).setZero();
    } else if (length > kZeroNormalLength) {
      normals.row(g) /= length;
    } else {
      normals.row(g).setZero();
    }
  }
  positions_ = std::move(positions);
  normals_ = std::move(normals);
  return static_cast<std::size_t>(n - groups);
}

void PointSet::flipNormals() { normals_ = -normals_; }

void checkFittable(const PointSet& points, const std::string& source) {
  const std::size_t n = points.size();
  if (n < 10) {
    throw InvalidArgument(source + ": only " + std::to_string(n) + " point" + (n == 1 ? "" : "s") +
                          "; fitting needs at least 10");
  }
  const Points& p = points.positions();
  const Eigen::AlignedBox3d box = points.bounds();
  const double diagonal = box.diagonal().norm();
  const double magnitude =
      std::max(box.min().cwiseAbs().maxCoeff(), box.max().cwiseAbs().maxCoeff());
  // Coincident: no extent at all, or an extent below what doubles can resolve at that magnitude.
  if (!(diagonal > 1e-12 * magnitude)) {
    throw InvalidArgument(source + ": all " + std::to_string(n) +
                          " points are at the same position " + describePoint(p, 0) +
                          "; fitting needs a surface");
  }
  // Extents that the float32 device arithmetic and the meshes' units cannot carry (a cloud scaled by
  // 1e-45 gave empty meshes): refuse them rather than fit nothing.
  const double side = box.sizes().maxCoeff();
  if (side < 1e-20 || side > 1e20) {
    throw InvalidArgument(source + ": the cloud's extent " + describeNumber(side) +
                          " is outside 1e-20 .. 1e20; rescale the cloud (e.g. to millimetres)");
  }
  // Collinear: the second-largest covariance eigenvalue (a variance) is negligible against L².
  const Eigen::RowVector3d mean = p.colwise().mean();
  const Points centred = p.rowwise() - mean;
  const Eigen::Matrix3d covariance = centred.transpose() * centred / static_cast<double>(n);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance, Eigen::EigenvaluesOnly);
  if (eigen.eigenvalues()(1) <= 1e-10 * diagonal * diagonal) {
    throw InvalidArgument(source + ": all " + std::to_string(n) +
                          " points lie on one line; fitting needs a surface");
  }
  if (points.zeroNormals() == n) {
    throw InvalidArgument(source + ": all " + std::to_string(n) +
                          " normals are zero; fitting needs oriented normals");
  }
}

}  // namespace duplexfit
