// Helpers fit() shares with fitDistributed().
#pragma once

#include <Eigen/Core>

#include "duplexfit/fit.hpp"
#include "duplexfit/linalg.hpp"
#include "fit/constraints.hpp"

namespace duplexfit::detail {

/// @throws InvalidArgument naming the first bad field of `o`.
void checkFitOptions(const FitOptions& o);
/// The typical sample spacing: the square root of the median point area.
double medianSpacing(const Eigen::VectorXd& areas);

/// The constraint options of level with support `sigma` (normalised units): the offsets `deltas`, the
/// off-surface side (−1 outside, 1 inside, 0 none, 2 both) and the fit's tolerances and switches; the
/// neighbour searches poll `interrupter` (may be null).
ConstraintOptions levelConstraintOptions(const FitOptions& options, const std::vector<double>& deltas, double sigma,
                                         int offSurfaceSide, Interrupter* interrupter);
/// A level's solver options: options.solver with the absolute tolerance levelTolerance (when it has none)
/// and, below the finest level, the relative tolerance coarseTolerance.
SolverOptions levelSolverOptions(const FitOptions& options, bool finest);
/// Solves a level's system A w = b on the device as every level of a fit is solved: A and b uploaded in
/// options.precision, the preconditioner of options, PCG with levelSolverOptions. An empty b is a
/// converged solve with no weights. `monitor` (if not null) gets the solver's events.
SolveStats solveLevelSystem(const Device& device, const CsrMatrix& a, const Eigen::VectorXd& b, const FitOptions& options,
                            bool finest, Eigen::VectorXd& weights, Interrupter* monitor = nullptr);

}  // namespace duplexfit::detail
