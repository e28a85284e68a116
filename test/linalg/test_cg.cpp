// Preconditioned CG on the device against the reference path and Eigen's double ConjugateGradient,
// on random SPD and Wendland systems; non-convergence, breakdown and bad input are reported, not hung.
#include <doctest/doctest.h>

#include <Eigen/Cholesky>
#include <Eigen/IterativeLinearSolvers>
#include <limits>
#include <random>

#include "support/recording_interrupter.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/wendland.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

Eigen::VectorXd randomVector(Eigen::Index n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::VectorXd v(n);
  for (Eigen::Index i = 0; i < n; ++i) v[i] = u(rng);
  return v;
}

Eigen::VectorXd eigenSolve(const CsrMatrix& a, const Eigen::VectorXd& b) {
  Eigen::ConjugateGradient<Eigen::SparseMatrix<double, Eigen::RowMajor, Index>, Eigen::Lower | Eigen::Upper>
      cg;
  cg.setTolerance(1e-12);
  cg.setMaxIterations(100000);
  const auto m = a.toEigen();  // the solver keeps a reference: must outlive solve()
  cg.compute(m);
  Eigen::VectorXd x = cg.solve(b);
  REQUIRE(cg.info() == Eigen::Success);
  return x;
}

struct Solved {
  SolveStats stats;
  Eigen::VectorXd x;
};

Solved solveOn(const Device& d, const CsrMatrix& a, const Eigen::VectorXd& b, Precision p,
               const SolverOptions& options = {}, const Preconditioner* (*make)(const DeviceCsr&) = nullptr,
               Interrupter* interrupter = nullptr) {
  const DeviceCsr m = DeviceCsr::upload(d, a, p);
  const DeviceVector db = DeviceVector::upload(d, b, p);
  DeviceVector x(d, b.size() > 0 ? static_cast<std::size_t>(b.size()) : 0, p);
  const Preconditioner* pre = make != nullptr ? make(m) : nullptr;
  Solved s{solveCg(m, db, x, options, pre, interrupter), x.download()};
  delete pre;
  return s;
}

// A preconditioner without a diagonal: exercises the general (unfused) CG path.
class ScaledIdentity final : public Preconditioner {
 public:
  void apply(const DeviceVector& r, DeviceVector& z) const override {
    z.fill(0.0);
    axpy(0.5, r, z);
  }
  std::string name() const override { return "0.5*I"; }
};

const Preconditioner* makeScaledIdentity(const DeviceCsr&) { return new ScaledIdentity(); }

// The host matrix for the block Jacobi factory below (set by compareWithEigen).
const CsrMatrix* g_blockMatrix = nullptr;
const Preconditioner* makeBlockJacobi(const DeviceCsr& m) {
  return new BlockJacobiPreconditioner(m.device(), *g_blockMatrix, m.precision(), 7);
}

const Preconditioner* makeFsai(const DeviceCsr& m) {
  return new FsaiPreconditioner(m.device(), *g_blockMatrix, m.precision());
}

void compareWithEigen(const Device& dev, const CsrMatrix& a, unsigned seed) {
  const Eigen::VectorXd b = randomVector(a.rows, seed);
  const Eigen::VectorXd xe = eigenSolve(a, b);
  const Device ref = Device::reference();
  for (const Precision p : {Precision::Float, Precision::Double}) {
    if (p == Precision::Double && !dev.supportsDouble()) continue;
    CAPTURE(precisionName(p));
    SolverOptions options;
    options.relativeTolerance = p == Precision::Double ? 1e-10 : 1e-5;
    const Solved r = solveOn(ref, a, b, p, options);
    const Solved o = solveOn(dev, a, b, p, options);
    CHECK(r.stats.converged);
    CHECK(o.stats.converged);
    CHECK(o.stats.relativeResidual <= 10 * options.relativeTolerance);
    // Same algorithm, same precision: iteration counts agree closely.
    CHECK(std::abs(o.stats.iterations - r.stats.iterations) <= std::max(3, r.stats.iterations / 10));
    const double relErr = (o.x - xe).norm() / std::max(xe.norm(), 1e-300);
    CHECK(relErr <= (p == Precision::Double ? 1e-7 : 2e-3));
    CHECK((r.x - xe).norm() / std::max(xe.norm(), 1e-300) <= (p == Precision::Double ? 1e-7 : 2e-3));
    // The general path with another preconditioner converges to the same solution.
    const Solved g = solveOn(dev, a, b, p, options, makeScaledIdentity);
    CHECK(g.stats.converged);
    CHECK((g.x - xe).norm() / std::max(xe.norm(), 1e-300) <= (p == Precision::Double ? 1e-7 : 2e-3));
    // Block Jacobi (blocks of 7 rows, so the last block is partial) on both devices.
    g_blockMatrix = &a;
    for (const Device* d : {&ref, &dev}) {
      const Solved bj = solveOn(*d, a, b, p, options, makeBlockJacobi);
      CHECK(bj.stats.converged);
      CHECK((bj.x - xe).norm() / std::max(xe.norm(), 1e-300) <= (p == Precision::Double ? 1e-7 : 2e-3));
      // FSAI (the default pattern), likewise.
      const Solved fs = solveOn(*d, a, b, p, options, makeFsai);
      CHECK(fs.stats.converged);
      CHECK((fs.x - xe).norm() / std::max(xe.norm(), 1e-300) <= (p == Precision::Double ? 1e-7 : 2e-3));
    }
  }
}

}  // namespace

TEST_SUITE("linalg") {
  TEST_CASE("cg: device solution matches Eigen's double CG on random SPD systems") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    for (const int n : {1, 2, 65, 1000, 5003}) {
      CAPTURE(n);
      compareWithEigen(dev, testing::randomSpdMatrix(n, 15, 100u + static_cast<unsigned>(n)), 17u);
    }
  }

  TEST_CASE("cg: device solution matches Eigen's double CG on Wendland sphere systems") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const int n = 2000;
    const double sigma = testing::sigmaForNonZeros(testing::Shape::Sphere, n, 0.1, 40.0);
    const testing::LevelCentres c = testing::levelCentres(testing::Shape::Sphere, n, 0.1, sigma);
    compareWithEigen(dev, assembleWendland(c.centres, sigma), 5u);
    compareWithEigen(dev, assembleWendland(c.centres, sigma, 0.3), 6u);  // approximation mode λ > 0
  }

  TEST_CASE("cg: block Jacobi applies the exact block inverses, fused and plain, device and reference") {
    const CsrMatrix a = testing::randomSpdMatrix(1003, 12, 77u);
    const Eigen::VectorXd r = randomVector(a.rows, 8u);
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    const Eigen::MatrixXd dense = Eigen::MatrixXd(a.toEigen());
    for (const int bs : {1, 16, 33}) {
      // Expected: solve each diagonal block exactly.
      Eigen::VectorXd expected(a.rows);
      for (Index base = 0; base < a.rows; base += bs) {
        const Index m = std::min<Index>(bs, a.rows - base);
        expected.segment(base, m) = dense.block(base, base, m, m).llt().solve(r.segment(base, m));
      }
      for (const Device& d : devices) {
        CAPTURE(bs);
        CAPTURE(d.info().spec);
        const BlockJacobiPreconditioner pre(d, a, Precision::Double, bs);
        const DeviceVector dr = DeviceVector::upload(d, r, Precision::Double);
        DeviceVector z(d, static_cast<std::size_t>(a.rows), Precision::Double);
        pre.apply(dr, z);
        CHECK((z.download() - expected).cwiseAbs().maxCoeff() <= 1e-12);
        z.fill(0.0);
        const double rz = pre.applyDot(dr, z);
        CHECK((z.download() - expected).cwiseAbs().maxCoeff() <= 1e-12);
        CHECK(rz == doctest::Approx(r.dot(expected)).epsilon(1e-12));
      }
    }
    // In float, 16-row blocks take the CPU kernel's 8-wide path for the whole blocks of each chunk (the
    // rows before the first and after the last through the per-row loop): the same z as the plain kernel.
    if (const Device* d = testing::openclTestDevice()) {
      Eigen::VectorXd expected(a.rows);
      for (Index base = 0; base < a.rows; base += 16) {
        const Index m = std::min<Index>(16, a.rows - base);
        expected.segment(base, m) = dense.block(base, base, m, m).llt().solve(r.segment(base, m));
      }
      const BlockJacobiPreconditioner pre(*d, a, Precision::Float, 16);
      const DeviceVector dr = DeviceVector::upload(*d, r, Precision::Float);
      DeviceVector z(*d, static_cast<std::size_t>(a.rows), Precision::Float);
      pre.apply(dr, z);
      const Eigen::VectorXd plain = z.download();
      const double scale = expected.cwiseAbs().maxCoeff();
      CHECK((plain - expected).cwiseAbs().maxCoeff() <= 1e-4 * scale);
      z.fill(0.0);
      const double rz = pre.applyDot(dr, z);
      CHECK((z.download() - plain).cwiseAbs().maxCoeff() <= 1e-6 * scale);
      CHECK(rz == doctest::Approx(r.dot(expected)).epsilon(1e-4));
    }
  }

  TEST_CASE("cg: FSAI is the exact inverse with every coupling, Jacobi with none, and cuts Wendland iterations") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const Device ref = Device::reference();
    // A small Wendland system whose rows couple to every other row (support wider than the cloud).
    const Points few = testing::fibonacciSphere(40, 0.5);
    const CsrMatrix dense = assembleWendland(few, 1.5);
    REQUIRE(dense.nonZeros() == 40u * 40u);
    const Eigen::VectorXd r = randomVector(40, 3u);
    const Eigen::VectorXd exact = dense.toEigen().toDense().llt().solve(r);
    const Eigen::VectorXd diag = dense.diagonal();
    for (const Device* d : {&ref, &dev}) {
      CAPTURE(d->isReference());
      for (const Precision p : {Precision::Float, Precision::Double}) {
        if (p == Precision::Double && !d->supportsDouble()) continue;
        CAPTURE(precisionName(p));
        const double tol = p == Precision::Double ? 1e-8 : 2e-3;
        const DeviceVector dr = DeviceVector::upload(*d, r, p);
        DeviceVector z(*d, 40, p);
        // every lower coupling kept: G is the inverse of A's Cholesky factor (scaled), so Gᵀ G = A⁻¹
        const FsaiPreconditioner full(*d, dense, p, 0.0, 64);
        CHECK(full.fallbackRows() == 0u);
        full.apply(dr, z);
        CHECK((z.download() - exact).norm() <= tol * exact.norm());
        // none kept: z = r / a_ii
        const FsaiPreconditioner none(*d, dense, p, 0.0, 0);
        CHECK(none.entriesPerRow() == 1.0);
        none.apply(dr, z);
        CHECK((z.download() - r.cwiseQuotient(diag)).norm() <= tol * r.norm());
        // From the uploaded matrix (its validation and diagonal reused): the same preconditioner bit for
        // bit, with every coupling, with the three strongest of 39 (row i keeps min(i, 3) + 1 entries) and
        // with the default threshold; a host matrix that is not the uploaded one is refused.
        const DeviceCsr up = DeviceCsr::upload(*d, dense, p);
        for (const auto& [threshold, k] : {std::pair<double, int>{0.0, 64}, {0.0, 3}, {0.2, 32}}) {
          CAPTURE(threshold);
          CAPTURE(k);
          const FsaiPreconditioner fresh(*d, dense, p, threshold, k), reused(up, dense, threshold, k);
          CHECK(fresh.entriesPerRow() == reused.entriesPerRow());
          DeviceVector z2(*d, 40, p);
          fresh.apply(dr, z);
          reused.apply(dr, z2);
          CHECK(z.download() == z2.download());
          if (k == 3) CHECK(reused.entriesPerRow() == doctest::Approx((1 + 2 + 3 + 4 * 37) / 40.0));
        }
        const CsrMatrix smaller = assembleWendland(few.topRows(39), 1.5);
        CHECK_THROWS_WITH_AS(FsaiPreconditioner(up, smaller), doctest::Contains("not the uploaded one"), InvalidArgument);
      }
    }
    // On a Wendland level system (40 non-zeros a row) FSAI with its default pattern (a few couplings a
    // row) converges to the same solution in far fewer iterations than block Jacobi.
    const int n = 3000;
    const double sigma = testing::sigmaForNonZeros(testing::Shape::Sphere, n, 0.1, 40.0);
    const testing::LevelCentres c = testing::levelCentres(testing::Shape::Sphere, n, 0.1, sigma);
    const CsrMatrix a = assembleWendland(c.centres, sigma);
    const Eigen::VectorXd b = randomVector(a.rows, 9u);
    const Eigen::VectorXd xe = eigenSolve(a, b);
    g_blockMatrix = &a;
    SolverOptions options;
    options.relativeTolerance = 1e-5;
    const Solved bj = solveOn(dev, a, b, Precision::Float, options, [](const DeviceCsr& m) -> const Preconditioner* {
      return new BlockJacobiPreconditioner(m.device(), *g_blockMatrix, m.precision(), 16);
    });
    const Solved fs = solveOn(dev, a, b, Precision::Float, options, makeFsai);
    const FsaiPreconditioner pattern(dev, a, Precision::Float);
    MESSAGE("Wendland sphere, " << a.rows << " rows: block Jacobi " << bj.stats.iterations << " iterations, FSAI "
                                << fs.stats.iterations << " (" << pattern.entriesPerRow() << " entries a row)");
    CHECK(pattern.entriesPerRow() < 10.0);
    CHECK(bj.stats.converged);
    CHECK(fs.stats.converged);
    CHECK((fs.x - xe).norm() <= 2e-3 * xe.norm());
    CHECK(2 * fs.stats.iterations <= bj.stats.iterations);
    // A matrix that is not positive definite on its diagonal is refused, naming the row.
    CsrMatrix bad = dense;
    bad.values[static_cast<std::size_t>(bad.rowPtr[7] + 7)] = -1.0;
    CHECK_THROWS_WITH_AS(FsaiPreconditioner(dev, bad, Precision::Float), doctest::Contains("diagonal entry 7"),
                         InvalidArgument);
  }

  TEST_CASE("cg: n = 0 and b = 0 return at once") {
    const Device ref = Device::reference();
    CsrMatrix empty;
    const Solved s = solveOn(ref, empty, Eigen::VectorXd(0), Precision::Double);
    CHECK(s.stats.converged);
    CHECK(s.stats.iterations == 0);
    const CsrMatrix a = testing::randomSpdMatrix(10, 3, 1u);
    const Solved z = solveOn(ref, a, Eigen::VectorXd::Zero(10), Precision::Double);
    CHECK(z.stats.reason == StopReason::ZeroRhs);
    CHECK(z.x.cwiseAbs().maxCoeff() == 0.0);
  }

  TEST_CASE("cg: the iteration cap stops a slow solve and reports it") {
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    const int n = 1500;
    const double sigma = testing::sigmaForNonZeros(testing::Shape::Sphere, n, 0.1, 40.0);
    const testing::LevelCentres c = testing::levelCentres(testing::Shape::Sphere, n, 0.1, sigma);
    const CsrMatrix a = assembleWendland(c.centres, sigma);
    const Eigen::VectorXd b = randomVector(a.rows, 3u);
    for (const Device& d : devices) {
      SolverOptions options;
      options.maxIterations = 5;
      options.relativeTolerance = 1e-12;
      const Solved s = solveOn(d, a, b, Precision::Float, options);
      CHECK_FALSE(s.stats.converged);
      CHECK(s.stats.reason == StopReason::IterationLimit);
      CHECK(s.stats.iterations == 5);
      CHECK(s.stats.relativeResidual < 1.0);
    }
  }

  TEST_CASE("cg: an indefinite matrix stops with a breakdown report, no hang") {
    CsrMatrix a;  // [[1, 2], [2, 1]]: eigenvalues 3 and −1
    a.rows = a.cols = 2;
    a.rowPtr = {0, 2, 4};
    a.colIdx = {0, 1, 0, 1};
    a.values = {1.0, 2.0, 2.0, 1.0};
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    Eigen::VectorXd b(2);
    b << 1.0, -1.0;  // the eigenvector of −1: pᵀAp < 0 at the first step
    for (const Device& d : devices) {
      const Solved s = solveOn(d, a, b, Precision::Float);
      CHECK_FALSE(s.stats.converged);
      CHECK(s.stats.reason == StopReason::Breakdown);
    }
    // A symmetric matrix with a negative diagonal cannot be Jacobi-preconditioned: clear error.
    a.values = {-1.0, 0.5, 0.5, 1.0};
    CHECK_THROWS_AS(solveOn(Device::reference(), a, b, Precision::Double), InvalidArgument);
  }

  TEST_CASE("cg: a non-finite right-hand side is reported as NonFinite") {
    const CsrMatrix a = testing::randomSpdMatrix(20, 4, 2u);
    Eigen::VectorXd b = Eigen::VectorXd::Ones(20);
    b[7] = std::numeric_limits<double>::quiet_NaN();
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    for (const Device& d : devices) {
      const Solved s = solveOn(d, a, b, Precision::Float);
      CHECK_FALSE(s.stats.converged);
      CHECK(s.stats.reason == StopReason::NonFinite);
    }
  }

  TEST_CASE("cg: the progress callback sees iterations and can cancel") {
    const int n = 1500;
    const double sigma = testing::sigmaForNonZeros(testing::Shape::Sphere, n, 0.1, 40.0);
    const testing::LevelCentres c = testing::levelCentres(testing::Shape::Sphere, n, 0.1, sigma);
    const CsrMatrix a = assembleWendland(c.centres, sigma);
    const Eigen::VectorXd b = randomVector(a.rows, 4u);
    SolverOptions options;
    options.progressInterval = 2;
    testing::RecordingInterrupter recorder;
    recorder.stopWhen = [](const testing::RecordingInterrupter& i) { return i.events.back().iteration >= 6; };
    const Solved s = solveOn(Device::reference(), a, b, Precision::Double, options, nullptr, &recorder);
    CHECK(s.stats.reason == StopReason::Cancelled);
    CHECK(s.stats.iterations == 6);
    REQUIRE(recorder.events.size() == 3);
    for (std::size_t i = 0; i < recorder.events.size(); ++i) {
      CHECK(recorder.events[i].stage == FitStage::Solve);
      CHECK(recorder.events[i].iteration == static_cast<int>(2 * (i + 1)));
      CHECK(recorder.events[i].residual > 0.0);
    }
  }

  TEST_CASE("cg: a system larger than the max allocation is a clear DeviceError") {
    const CsrMatrix a = testing::randomSpdMatrix(20000, 20, 5u);
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    for (const Device& d : devices) {
      DeviceOptions options;
      options.maxAllocBytes = 1 << 20;  // 1 MiB; the values need ~1.6 MiB in float
      const Device capped = Device::open(d.info().spec, options);
      try {
        (void)DeviceCsr::upload(capped, a, Precision::Float);
        FAIL("expected DeviceError");
      } catch (const DeviceError& e) {
        CHECK(std::string(e.what()).find("non-zeros") != std::string::npos);
        CHECK(std::string(e.what()).find("MiB") != std::string::npos);
      }
    }
  }
}
