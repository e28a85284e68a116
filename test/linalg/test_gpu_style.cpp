// The GPU-style kernels (work-group reductions, row-per-group SpMV, group CG updates) run on the CPU
// test device too, by opening it with DUPLEXFIT_REDUCTIONS=group, and must agree with the reference.
#include <doctest/doctest.h>

#include <cstdlib>
#include <random>

#include "duplexfit/linalg.hpp"
#include "duplexfit/wendland.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

Device openWith(const Device& base, const char* reductions, const char* wg) {
  setenv("DUPLEXFIT_REDUCTIONS", reductions, 1);
  setenv("DUPLEXFIT_WG_SIZE", wg, 1);
  Device d = Device::open(base.info().spec);
  unsetenv("DUPLEXFIT_REDUCTIONS");
  unsetenv("DUPLEXFIT_WG_SIZE");
  return d;
}

}  // namespace

TEST_SUITE("linalg") {
  TEST_CASE("gpu-style kernels: group reductions and row-per-group SpMV agree with the reference") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    for (const char* wg : {"64", "256"}) {
      CAPTURE(wg);
      const Device g = openWith(dev, "group", wg);
      REQUIRE_FALSE(g.tuning().chunkReductions);
      const Device ref = Device::reference();
      const double sigma = testing::sigmaForNonZeros(testing::Shape::Torus, 4001, 0.05, 40.0);
      const CsrMatrix a = assembleWendland(testing::levelCentres(testing::Shape::Torus, 4001, 0.05, sigma).centres, sigma);
      std::mt19937 rng(5);
      std::uniform_real_distribution<double> u(-1, 1);
      Eigen::VectorXd b(a.rows);
      for (Index i = 0; i < a.rows; ++i) b[i] = u(rng);
      for (const Precision p : {Precision::Float, Precision::Double}) {
        if (p == Precision::Double && !g.supportsDouble()) continue;
        CAPTURE(precisionName(p));
        const double tol = p == Precision::Double ? 1e-10 : 1e-4;
        // dot / norm over sizes that are not multiples of anything.
        for (const Index n : {Index{1}, Index{255}, Index{257}, a.rows}) {
          const Eigen::VectorXd x = b.head(n);
          const DeviceVector dx = DeviceVector::upload(g, x, p);
          CHECK(dot(dx, dx) == doctest::Approx(x.squaredNorm()).epsilon(tol));
        }
        const DeviceCsr m = DeviceCsr::upload(g, a, p);
        const DeviceVector db = DeviceVector::upload(g, b, p);
        DeviceVector y(g, static_cast<std::size_t>(a.rows), p);
        spmv(m, db, y, SpmvKernel::RowPerGroup);
        const Eigen::VectorXd yRef = a.multiply(b);
        CHECK((y.download() - yRef).cwiseAbs().maxCoeff() <= tol * yRef.cwiseAbs().maxCoeff() * 10);
        // CG with the fused Jacobi path and with block Jacobi (group kernels) against the reference.
        SolverOptions o;
        o.relativeTolerance = p == Precision::Double ? 1e-9 : 1e-5;
        for (const bool block : {false, true}) {
          CAPTURE(block);
          Eigen::VectorXd sol[2];
          int k = 0;
          for (const Device* d : {&ref, &g}) {
            const DeviceCsr md = DeviceCsr::upload(*d, a, p);
            const DeviceVector bd = DeviceVector::upload(*d, b, p);
            DeviceVector xd(*d, static_cast<std::size_t>(a.rows), p);
            const BlockJacobiPreconditioner bj(*d, a, p, 16);
            const SolveStats s = solveCg(md, bd, xd, o, block ? &bj : nullptr);
            CHECK(s.converged);
            sol[k++] = xd.download();
          }
          CHECK((sol[0] - sol[1]).norm() / sol[0].norm() <= (p == Precision::Double ? 1e-7 : 1e-3));
        }
      }
    }
  }
}
