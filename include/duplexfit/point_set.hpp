// PointSet: an oriented point cloud (positions with unit normals), the input of fitting.
#pragma once

#include <string>

#include <Eigen/Geometry>

#include "duplexfit/types.hpp"

namespace duplexfit {

/// Positions and normals of n points (#P×3 each). Normals are unit length or exactly zero (a point with
/// an unusable normal: it constrains f = 0 but gets no offset or off-surface companions, docs/method.md §3.3).
class PointSet {
 public:
  PointSet() = default;
  /// Normalises the normals (lengths ≤ 1e-12 become zero).
  /// @throws InvalidArgument on a row-count mismatch or a non-finite value (naming the point index).
  PointSet(Points positions, Points normals);
  /// Rows taken from other PointSets (normals already unit or zero), checked but not normalised again:
  /// normalising is not idempotent in the last bit, and the distributed fit must see the same normals as
  /// a fit of the whole cloud. @throws as the constructor.
  static PointSet fromNormalized(Points positions, Points normals);

  std::size_t size() const noexcept { return static_cast<std::size_t>(positions_.rows()); }
  const Points& positions() const noexcept { return positions_; }
  const Points& normals() const noexcept { return normals_; }
  /// Axis-aligned bounding box of the positions (empty box for an empty set).
  Eigen::AlignedBox3d bounds() const;
  /// Number of points whose normal is zero.
  std::size_t zeroNormals() const;

  /// Merges points with identical positions (after rounding to tolerance·bbox diagonal, 0 = exact),
  /// averaging and renormalising their normals. Keeps the first occurrence's order. Returns the number of
  /// points removed.
  std::size_t mergeDuplicates(double relativeTolerance = 0.0);

  /// Flips every normal (ν = −n: the fit wants normals pointing into the solid, docs/method.md §1).
  void flipNormals();

 private:
  Points positions_;
  Points normals_;
};

/// Checks that a cloud can be fitted: at least 10 points, not all coincident, not all on one line,
/// not all normals zero. @throws InvalidArgument whose message starts with `source` (e.g. the file name).
void checkFittable(const PointSet& points, const std::string& source);

}  // namespace duplexfit
