// The CPU baseline of duplexfit-bench: Eigen's row-major SpMV and ConjugateGradient<…, Lower|Upper> with
// its default Jacobi (diagonal) preconditioner, on the same matrix in the same precision, on all OpenMP
// threads (Eigen parallelises the row-major sparse × dense product; its vector operations run on one).
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>

#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"
#include "harness.hpp"

namespace duplexfit::bench {

struct EigenSpmvResult {
  Stats ms;             ///< y = A·x, wall ms per product
  double maxRelError;   ///< max|y − y_ref| / max|y_ref| against the double host product
};

struct EigenCgResult {
  Stats ms;                  ///< wall ms of compute(A) + solve(b) from x = 0
  double setupMs = 0.0;      ///< compute(A) alone (the diagonal preconditioner), median
  int iterations = 0;
  double estimatedError = 0.0;   ///< Eigen's own ‖r‖/‖b‖
  double relativeResidual = 0.0; ///< ‖b − A·x‖/‖b‖ recomputed in double on the host
  bool converged = false;
  std::string status;
};

/// The matrix converted once to Eigen in one precision.
class EigenBaseline {
 public:
  EigenBaseline(const CsrMatrix& a, Precision precision);
  ~EigenBaseline();
  EigenBaseline(const EigenBaseline&) = delete;
  EigenBaseline& operator=(const EigenBaseline&) = delete;

  /// One untimed product, then `trials` timed ones.
  EigenSpmvResult spmv(const Eigen::VectorXd& x, const Eigen::VectorXd& yRef, int trials) const;
  /// One untimed single-iteration solve, then `trials` full solves to ‖r‖ ≤ tol·‖b‖.
  EigenCgResult cg(const CsrMatrix& a, const Eigen::VectorXd& b, double tolerance, int maxIterations,
                   int trials) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace duplexfit::bench
