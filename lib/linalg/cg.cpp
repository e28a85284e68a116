// Preconditioned conjugate gradients (docs/method.md §5). The iteration is written once over device
// operations; with a diagonal preconditioner it uses the fused kernels (3 passes per iteration:
// SpMV+p·q, x/r update + r·z + r·r, new direction), otherwise plain BLAS-1 calls. Non-convergence,
// breakdown (not SPD) and non-finite values are reported in SolveStats, never thrown.
#include <chrono>
#include <cmath>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "linalg/ops.hpp"
#include "linalg/storage.hpp"

namespace duplexfit {

const char* stopReasonName(StopReason reason) noexcept {
  switch (reason) {
    case StopReason::Converged:
      return "converged";
    case StopReason::ZeroRhs:
      return "zero right-hand side";
    case StopReason::IterationLimit:
      return "iteration limit";
    case StopReason::Breakdown:
      return "breakdown (matrix not positive definite)";
    case StopReason::NonFinite:
      return "non-finite value";
    case StopReason::Stagnated:
      return "stagnated above the tolerance";
    default:
      return "cancelled";
  }
}

JacobiPreconditioner::JacobiPreconditioner(const DeviceCsr& a) {
  const Eigen::VectorXd& d = a.diagonal();
  Eigen::VectorXd inv(d.size());
  for (Eigen::Index i = 0; i < d.size(); ++i) {
    if (!(d[i] > 0.0) || !std::isfinite(d[i])) {
      throw InvalidArgument("Jacobi preconditioner: diagonal entry " + std::to_string(i) + " is " +
                            std::to_string(d[i]) + "; a symmetric positive definite matrix needs d_ii > 0");
    }
    inv[i] = 1.0 / d[i];
  }
  invDiag_ = DeviceVector::upload(a.device(), inv, a.precision());
}

void JacobiPreconditioner::apply(const DeviceVector& r, DeviceVector& z) const { detail::vmul(invDiag_, r, z); }

namespace {

bool finite(double v) { return std::isfinite(v); }

}  // namespace

SolveStats solveCg(const DeviceCsr& a, const DeviceVector& b, DeviceVector& x, const SolverOptions& options,
                   const Preconditioner* preconditioner, Interrupter* interrupter) {
  const auto start = std::chrono::steady_clock::now();
  const std::size_t n = a.rows();
  if (a.rows() != a.cols()) throw InvalidArgument("solveCg: the matrix is not square");
  if (b.size() != n || x.size() != n) {
    throw InvalidArgument("solveCg: matrix has " + std::to_string(n) + " rows but b has " +
                          std::to_string(b.size()) + " and x " + std::to_string(x.size()) + " entries");
  }
  if (options.maxIterations < 0) throw InvalidArgument("solveCg: maxIterations must be >= 0");
  if (options.relativeTolerance < 0.0 || !finite(options.relativeTolerance)) {
    throw InvalidArgument("solveCg: relativeTolerance must be finite and >= 0");
  }
  SolveStats stats;
  stats.tolerance = options.relativeTolerance > 0.0 ? options.relativeTolerance
                    : a.precision() == Precision::Double ? 1e-6
                                                         : 1e-5;
  stats.absoluteTolerance = options.absoluteTolerance;
  auto finish = [&](StopReason reason) {
    stats.reason = reason;
    stats.converged = reason == StopReason::Converged || reason == StopReason::ZeroRhs;
    stats.seconds = secondsSince(start);
    return stats;
  };
  if (n == 0) return finish(StopReason::ZeroRhs);
  detail::checkCompatible("solveCg", b, x);
  if (b.precision() != a.precision() || b.device().impl() != a.device().impl()) {
    throw InvalidArgument("solveCg: matrix and vectors differ in device or precision");
  }

  std::unique_ptr<JacobiPreconditioner> ownJacobi;
  if (preconditioner == nullptr) {
    ownJacobi = std::make_unique<JacobiPreconditioner>(a);
    preconditioner = ownJacobi.get();
  }
  const DeviceVector* dinv = options.useFusedKernels ? preconditioner->inverseDiagonal() : nullptr;
  const Device& device = a.device();
  const Precision prec = a.precision();
  const SpmvKernel kernel = options.spmvKernel;

  const double bnorm = norm2(b);
  if (!finite(bnorm)) return finish(StopReason::NonFinite);
  if (bnorm == 0.0) {
    x.fill(0.0);
    return finish(StopReason::ZeroRhs);
  }
  const double target = stats.tolerance * bnorm;

  DeviceVector r(device, n, prec), p(device, n, prec), q(device, n, prec), z(device, n, prec);
  // r = b − A x, z = M⁻¹ r, p = z; returns r·z, r·r and max|r|. Also used to restart on residual drift.
  auto restart = [&]() -> detail::CgSums {
    spmv(a, x, q, kernel);
    r.fill(0.0);
    axpy(1.0, b, r);
    axpy(-1.0, q, r);
    const double rz = preconditioner->applyDot(r, z);
    p.fill(0.0);
    axpy(1.0, z, p);
    const detail::CgSums xr = detail::cgUpdateXR(0.0, p, q, x, r);  // α = 0: only r·r and max|r|
    return {rz, xr.rr, xr.rmax};
  };
  // The true residual b − A x into z; returns (‖·‖₂, max|·|).
  auto trueResidual = [&]() -> std::pair<double, double> {
    spmv(a, x, q, kernel);
    z.fill(0.0);
    axpy(1.0, b, z);
    axpy(-1.0, q, z);
    const detail::CgSums s = detail::cgUpdateXR(0.0, p, q, x, z);
    return {std::sqrt(std::max(s.rr, 0.0)), s.rmax};
  };
  const double absTol = options.absoluteTolerance;
  auto converged = [&](double norm, double maxAbs) {
    return norm <= target || (absTol > 0.0 && maxAbs <= absTol);
  };
  detail::CgSums sums = restart();
  bool haveTrue = false;  // z holds b − A x for the current x (skip recomputing it at the end)
  double trueNormLast = 0.0, trueMaxLast = 0.0;
  int restarts = 0;
  int it = 0;
  StopReason reason = StopReason::IterationLimit;
  for (;;) {
    const double rnorm = std::sqrt(std::max(sums.rr, 0.0));
    stats.recurrenceResidual = rnorm / bnorm;
    if (!finite(sums.rz) || !finite(sums.rr)) {
      reason = StopReason::NonFinite;
      break;
    }
    if (converged(rnorm, sums.rmax)) {
      // Guard against drift of the recursive residual (notably in float): check the true one and
      // restart from it, at most a few times.
      const auto [trueNorm, trueMax] = trueResidual();
      haveTrue = true;
      trueNormLast = trueNorm;
      trueMaxLast = trueMax;
      if (trueNorm <= target || (absTol > 0.0 && trueMax <= absTol)) {
        reason = StopReason::Converged;
        break;
      }
      if (restarts >= 3 || it >= options.maxIterations) {
        reason = StopReason::Stagnated;
        break;
      }
      ++restarts;
      haveTrue = false;
      sums = restart();
      continue;
    }
    if (it >= options.maxIterations) break;
    if (!(sums.rz > 0.0)) {
      reason = StopReason::Breakdown;
      break;
    }
    const double pq = detail::spmvDot(a, p, q, kernel);
    if (!finite(pq)) {
      reason = StopReason::NonFinite;
      break;
    }
    if (!(pq > 0.0)) {
      reason = StopReason::Breakdown;
      break;
    }
    const double alpha = sums.rz / pq;
    const double rzOld = sums.rz;
    if (dinv != nullptr) {
      sums = detail::cgUpdate(alpha, p, q, *dinv, x, r);
    } else {
      sums = detail::cgUpdateXR(alpha, p, q, x, r);
      sums.rz = preconditioner->applyDot(r, z);
    }
    const double beta = sums.rz / rzOld;
    if (dinv != nullptr) {
      detail::cgDirection(beta, r, *dinv, p);
    } else {
      xpay(z, beta, p);
    }
    ++it;
    if (interrupter != nullptr && options.progressInterval > 0 && it % options.progressInterval == 0) {
      FitEvent event;
      event.stage = FitStage::Solve;
      event.iteration = it;
      event.residual = std::sqrt(std::max(sums.rr, 0.0)) / bnorm;
      interrupter->fitEvent(event);
      if (interrupter->wasInterrupted()) {
        reason = StopReason::Cancelled;
        break;
      }
    }
  }
  stats.iterations = it;
  if (!haveTrue || reason != StopReason::Converged) {
    const auto [finalNorm, finalMax] = trueResidual();
    trueNormLast = finalNorm;
    trueMaxLast = finalMax;
  }
  stats.relativeResidual = trueNormLast / bnorm;
  stats.maxResidual = trueMaxLast;
  if (reason == StopReason::Converged && !finite(stats.relativeResidual)) reason = StopReason::NonFinite;
  return finish(reason);
}

}  // namespace duplexfit
