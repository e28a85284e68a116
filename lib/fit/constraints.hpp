// The centres of one level (docs/method.md §3): surface points (target 0), offset points q = p + δν kept by
// the validity test (target δ), off-surface points (target ±d_k), merged where closer than mergeDistance·σ_k; optionally (medial) the rejected companions moved onto the
// medial surface with their true distance as target.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "duplexfit/neighbors.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::detail {

struct ConstraintOptions {
  std::vector<double> offsets;  ///< signed δ, normalised units, δ > 0 along ν (inward)
  double offSurfaceDistance = 0.0;  ///< d_k = σ_k/10
  /// +1: off-surface points along +ν (inside), −1: along −ν (outside), 0: none, 2: both sides
  int offSurfaceSide = -1;
  double validityTolerance = 1e-2;  ///< η
  double mergeDistance = 0.0;       ///< FitOptions::mergeDistance (1e-2) × σ_k
  double sigma = 0.0;               ///< σ_k: the cell of the merge's grid (at least mergeDistance)
  bool dropZeroNormalPoints = false;
  /// Also reject a companion q on the wrong side of its nearest other point's tangent plane (FitOptions::sideTest).
  bool tangentSideTest = false;
  /// Also reject a companion closer than |δ|/2 to a crease point's tangent plane across a convex edge
  /// (FitOptions::creaseTest; CreasePlanes in constraints.cpp).
  bool creaseTest = true;
  /// Largest disc radius of that test (0: none); the fit passes 2σ_k, a bound the same in every rank of the
  /// distributed fit, whose data radius covers it.
  double creaseRadiusCap = 0.0;
  /// Move companions rejected by the distance test onto the medial surface (FitOptions::medialConstraints).
  bool medial = false;
  double minMedialFraction = 0.1;  ///< ... kept when moved back to at least this fraction of the step
  /// Polled inside the neighbour searches (may be null): a search over millions of points can be stopped.
  Interrupter* interrupter = nullptr;
};

struct LevelConstraints {
  Points centres;
  Eigen::VectorXd targets;
  std::size_t surface = 0;
  std::vector<std::size_t> offsetCandidates, offsetKept;
  std::size_t offSurfaceCandidates = 0, offSurfaceKept = 0;
  std::vector<std::size_t> offsetMedial;  ///< per offset: rejected candidates kept on the medial surface
  std::size_t offSurfaceMedial = 0;
  std::size_t merged = 0;
  /// The row of the level's points each centre derives from (its own row for a surface point, the source
  /// of an offset, off-surface or medial point): the distributed fit keeps the centres of the points a
  /// rank owns.
  std::vector<Eigen::Index> sources;
  /// Rows of `centres` that are valid offset points of offset j (for E_δ), per offset.
  std::vector<std::vector<Eigen::Index>> offsetRows;
  /// Pairs (input point index, centre row) of the surface points kept as centres, and the input
  /// indices of surface points that were merged away or dropped (for E_0).
  std::vector<std::pair<Eigen::Index, Eigen::Index>> surfaceCentres;
  std::vector<Eigen::Index> surfaceNotCentres;
};

/// The offsets in input units (fractions of `side` when `relative`), each checked: non-zero and smaller
/// than the bounding box's largest side `side`. @throws InvalidArgument naming the offending offset.
std::vector<double> worldOffsets(const std::vector<double>& offsets, bool relative, double side);

/// The offset points p_i + step·ν_i of the points with a non-zero normal that pass the validity test (§3.1)
/// against all of `points` (the paper's test, for the separate-fit baseline: no crease-plane test); `sources`
/// receives the index of each kept point's p_i.
Points validOffsetPoints(const Points& points, const Points& normals, double step, double eta, bool sideTest,
                         std::vector<Eigen::Index>& sources);

/// Builds the level's centres from its points P^k and inward normals ν (unit or zero).
LevelConstraints buildConstraints(const Points& points, const Points& normals, const ConstraintOptions& options);

}  // namespace duplexfit::detail
