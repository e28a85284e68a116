// The generalized winding number of an oriented point cloud (docs/method.md, "Sign of empty space"):
// w(q) = Σ a_i (p_i − q)·n_i / (4π |p_i − q|³) with outward unit normals n_i and point areas a_i; ≈ 1 inside
// a closed sampled surface, ≈ 0 outside. Evaluated by the fast tree approximation of Barill et al. (2018,
// "Fast winding numbers for soups and clouds"): per octree node an area-weighted centre, its dipole and the
// second-order moment; a node far enough from q (|centre − q| > β·radius) answers by its expansion.
#pragma once

#include <memory>

#include <Eigen/Core>

#include "duplexfit/neighbors.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

struct WindingOptions {
  /// Accuracy: a node answers by its expansion when |centre − q| > β·(its radius); the second-order
  /// expansion's error is ~β⁻² of the node's share (measured in the tests: see test_winding.cpp).
  double beta = 3.0;
  int leafSize = 16;      ///< points per octree leaf (summed exactly)
  int areaNeighbors = 12; ///< neighbours for the point-area estimate (estimatePointAreas)
};

/// Area per point a_i from the local sampling density: the k nearest neighbours whose normals agree with
/// n_i (n_i·n_j > 0, so the far side of a thin wall does not count) projected into p_i's tangent plane;
/// a_i = π ρ² / m with ρ the largest projected distance among the m ≤ k agreeing neighbours.
/// Points with a zero normal get area 0. @throws InvalidArgument for mismatched sizes.
Eigen::VectorXd estimatePointAreas(const Points& positions, const Points& normals, int k = 12);
/// The same with a caller's index over `positions` (the same points in the same order), so that a caller
/// that needs that index anyway does not build a second one. @throws InvalidArgument also when the
/// index's size differs.
Eigen::VectorXd estimatePointAreas(const Points& positions, const Points& normals, int k, const NeighborIndex& index);

class WindingNumber {
 public:
  /// Areas estimated by estimatePointAreas(options.areaNeighbors). Normals point outward.
  WindingNumber(const Points& positions, const Points& outwardNormals, const WindingOptions& options = {});
  WindingNumber(const Points& positions, const Points& outwardNormals, const Eigen::VectorXd& areas,
                const WindingOptions& options = {});
  WindingNumber(WindingNumber&&) noexcept;
  WindingNumber& operator=(WindingNumber&&) noexcept;
  ~WindingNumber();

  /// The tree approximation at each query (multi-threaded).
  Eigen::VectorXd evaluate(const Points& queries) const;
  /// The same with another accuracy than the options' β (> 0; @throws InvalidArgument otherwise): β = 2 is
  /// about twice as fast as 3 and differs from it by up to 0.06 three sample spacings or more from the
  /// shared clouds (0.14 nearer), so a caller that only compares w with thresholds can take β = 2 first and
  /// ask again where it is close to one.
  Eigen::VectorXd evaluate(const Points& queries, double beta) const;
  /// The direct sum over all points (the oracle; O(n) per query).
  Eigen::VectorXd exact(const Points& queries) const;
  const Eigen::VectorXd& areas() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace duplexfit
