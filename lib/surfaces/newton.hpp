// Newton paths onto a level set, shared by the deviation measure and the projection (lib/surfaces).
#pragma once

#include <cmath>
#include <vector>

#include "duplexfit/mesh_finish.hpp"

namespace duplexfit::detail {

/// Moves each point of x towards {f = iso} by Newton steps x ← x − (f(x) − iso) ∇f/|∇f|², each at most
/// 1% of `side`, evaluating only the paths still going. A path has converged when |f − iso| ≤ 1e-6·side or
/// its first-order rest |f − iso|/|∇f| ≤ 1e-5·side; then converged[i] = 1 and rest[i] = min(rest, 1e-5·side).
/// A path that has not converged after `steps` steps (or meets ∇f = 0) keeps converged[i] = 0 and the
/// position it reached.
/// `start`, when given, holds f and ∇f at the starting points (rows of x), so that the first step does not
/// evaluate them again. `endGradients`, when given, receives ∇f at the final x of every converged path
/// (rows of the others are left zero). `endFirstOrder`, when given, receives |f − iso| / |∇f| at every
/// path's final x (each path's last step evaluated there; −1 where |∇f| < 1e-6, as the deviation measure).
struct NewtonStart {
  const Eigen::VectorXd& values;
  const Points& gradients;
};
void newtonPaths(const FieldGradientSampler& sampler, Points& x, double iso, double side, std::vector<char>& converged,
                 std::vector<double>& rest, int steps = 10, const NewtonStart* start = nullptr,
                 Points* endGradients = nullptr, std::vector<double>* endFirstOrder = nullptr);

/// The deviation measure's first-order distance from f and ∇f at a point: |f − iso| / |∇f|, −1 where
/// |∇f| < 1e-6.
inline double firstOrderDistance(double value, const Eigen::RowVector3d& gradient, double iso) {
  const double g = gradient.norm();
  return g >= 1e-6 ? std::abs(value - iso) / g : -1.0;
}

}  // namespace duplexfit::detail
