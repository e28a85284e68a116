// Eigen SpMV and ConjugateGradient baselines (see eigen_baseline.hpp). Built with -Wno-null-dereference:
// GCC's flow-sensitive warning fires inside Eigen's inlined sparse iterators (bench/CMakeLists.txt).
#include "eigen_baseline.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCore>

#include <algorithm>
#include <vector>

namespace duplexfit::bench {

namespace {

template <typename T>
using RowMajorMatrix = Eigen::SparseMatrix<T, Eigen::RowMajor, Index>;
template <typename T>
using Vector = Eigen::Matrix<T, Eigen::Dynamic, 1>;

template <typename T>
RowMajorMatrix<T> convert(const CsrMatrix& a) {
  RowMajorMatrix<T> m(a.rows, a.cols);
  m.resizeNonZeros(static_cast<Index>(a.nonZeros()));
  std::copy(a.rowPtr.begin(), a.rowPtr.end(), m.outerIndexPtr());
  std::copy(a.colIdx.begin(), a.colIdx.end(), m.innerIndexPtr());
  std::transform(a.values.begin(), a.values.end(), m.valuePtr(), [](double v) { return static_cast<T>(v); });
  return m;
}

template <typename T>
EigenSpmvResult timeSpmv(const RowMajorMatrix<T>& m, const Eigen::VectorXd& x, const Eigen::VectorXd& yRef,
                         int trials) {
  const Vector<T> xt = x.cast<T>();
  Vector<T> y(m.rows());
  y.noalias() = m * xt;  // warm-up (first touch of y)
  std::vector<double> ms;
  for (int t = 0; t < trials; ++t) {
    const double t0 = nowSeconds();
    y.noalias() = m * xt;
    ms.push_back((nowSeconds() - t0) * 1e3);
  }
  EigenSpmvResult r{Stats::of(ms), 0.0};
  const double scale = yRef.cwiseAbs().maxCoeff();
  r.maxRelError = (y.template cast<double>() - yRef).cwiseAbs().maxCoeff() / (scale > 0.0 ? scale : 1.0);
  return r;
}

template <typename T>
EigenCgResult timeCg(const RowMajorMatrix<T>& m, const CsrMatrix& a, const Eigen::VectorXd& b, double tol,
                     int maxIterations, int trials) {
  using Solver = Eigen::ConjugateGradient<RowMajorMatrix<T>, Eigen::Lower | Eigen::Upper>;
  const Vector<T> bt = b.cast<T>();
  {
    Solver warm;
    warm.setTolerance(static_cast<typename Solver::RealScalar>(tol));
    warm.setMaxIterations(1);
    warm.compute(m);
    const Vector<T> x = warm.solve(bt);
    (void)x;
  }
  EigenCgResult r;
  std::vector<double> total, setup;
  Vector<T> x;
  Solver solver;
  for (int t = 0; t < trials; ++t) {
    solver.setTolerance(static_cast<typename Solver::RealScalar>(tol));
    solver.setMaxIterations(maxIterations);
    const double t0 = nowSeconds();
    solver.compute(m);
    const double t1 = nowSeconds();
    x = solver.solve(bt);
    const double t2 = nowSeconds();
    total.push_back((t2 - t0) * 1e3);
    setup.push_back((t1 - t0) * 1e3);
  }
  r.ms = Stats::of(total);
  r.setupMs = Stats::of(setup).median;
  r.iterations = static_cast<int>(solver.iterations());
  r.estimatedError = static_cast<double>(solver.error());
  r.converged = solver.info() == Eigen::Success;
  r.status = r.converged ? "converged" : solver.info() == Eigen::NoConvergence ? "no convergence" : "failed";
  const Eigen::VectorXd xd = x.template cast<double>();
  r.relativeResidual = (b - a.multiply(xd)).norm() / b.norm();
  return r;
}

}  // namespace

struct EigenBaseline::Impl {
  Precision precision;
  RowMajorMatrix<float> f;
  RowMajorMatrix<double> d;
};

EigenBaseline::EigenBaseline(const CsrMatrix& a, Precision precision) : impl_(std::make_unique<Impl>()) {
  impl_->precision = precision;
  if (precision == Precision::Double) {
    impl_->d = convert<double>(a);
  } else {
    impl_->f = convert<float>(a);
  }
}

EigenBaseline::~EigenBaseline() = default;

EigenSpmvResult EigenBaseline::spmv(const Eigen::VectorXd& x, const Eigen::VectorXd& yRef, int trials) const {
  return impl_->precision == Precision::Double ? timeSpmv(impl_->d, x, yRef, trials)
                                               : timeSpmv(impl_->f, x, yRef, trials);
}

EigenCgResult EigenBaseline::cg(const CsrMatrix& a, const Eigen::VectorXd& b, double tolerance, int maxIterations,
                                int trials) const {
  return impl_->precision == Precision::Double ? timeCg(impl_->d, a, b, tolerance, maxIterations, trials)
                                               : timeCg(impl_->f, a, b, tolerance, maxIterations, trials);
}

}  // namespace duplexfit::bench
