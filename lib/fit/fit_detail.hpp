// Helpers fit() shares with fitDistributed().
#pragma once

#include <Eigen/Core>

#include "duplexfit/fit.hpp"

namespace duplexfit::detail {

/// @throws InvalidArgument naming the first bad field of `o`.
void checkFitOptions(const FitOptions& o);
/// The typical sample spacing: the square root of the median point area.
double medianSpacing(const Eigen::VectorXd& areas);

}  // namespace duplexfit::detail
