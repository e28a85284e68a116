// BLAS-1 on the OpenCL device against the reference path and against double arithmetic.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "linalg/ops.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

Eigen::VectorXd randomVector(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) v[i] = u(rng);
  return v;
}

// max |a − b|, 0 for empty vectors (Eigen's maxCoeff needs at least one element).
double maxDiff(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return a.size() == 0 ? 0.0 : (a - b).cwiseAbs().maxCoeff();
}

double tolFor(Precision p) { return p == Precision::Double ? 1e-12 : 2e-6; }

// Sizes around the work-group size, chunk size and odd large sizes.
const int kSizes[] = {0, 1, 2, 63, 64, 65, 511, 513, 4097, 100003};

}  // namespace

TEST_SUITE("linalg") {
  TEST_CASE("blas1: axpy, xpay, dot and norm agree with the reference and with double math") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const Device ref = Device::reference();
    for (const Precision p : {Precision::Float, Precision::Double}) {
      if (p == Precision::Double && !dev.supportsDouble()) continue;
      for (const int n : kSizes) {
        CAPTURE(n);
        CAPTURE(precisionName(p));
        const Eigen::VectorXd x = randomVector(n, 1u + static_cast<unsigned>(n));
        const Eigen::VectorXd y = randomVector(n, 2u + static_cast<unsigned>(n));
        const double scale = std::max(1.0, static_cast<double>(n));
        for (const Device* d : {&ref, &dev}) {
          DeviceVector dx = DeviceVector::upload(*d, x, p);
          DeviceVector dy = DeviceVector::upload(*d, y, p);
          axpy(0.75, dx, dy);
          const Eigen::VectorXd axpyExpected = 0.75 * x + y;
          CHECK(maxDiff(dy.download(), axpyExpected) <= 4 * tolFor(p));
          xpay(dx, -0.5, dy);
          const Eigen::VectorXd xpayExpected = x - 0.5 * axpyExpected;
          CHECK(maxDiff(dy.download(), xpayExpected) <= 8 * tolFor(p));
          const double dotValue = dot(dx, dy);
          CHECK(std::abs(dotValue - x.dot(xpayExpected)) <= tolFor(p) * scale * 4);
          CHECK(std::abs(norm2(dx) - x.norm()) <= tolFor(p) * std::sqrt(scale) * 4);
        }
        // Device and reference agree closely in the same precision.
        DeviceVector rx = DeviceVector::upload(ref, x, p), ry = DeviceVector::upload(ref, y, p);
        DeviceVector ox = DeviceVector::upload(dev, x, p), oy = DeviceVector::upload(dev, y, p);
        CHECK(std::abs(dot(rx, ry) - dot(ox, oy)) <= tolFor(p) * scale);
      }
    }
  }

  TEST_CASE("blas1: fused CG updates agree with the reference") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const Device ref = Device::reference();
    for (const Precision p : {Precision::Float, Precision::Double}) {
      if (p == Precision::Double && !dev.supportsDouble()) continue;
      for (const int n : kSizes) {
        CAPTURE(n);
        const Eigen::VectorXd pv = randomVector(n, 3), qv = randomVector(n, 4), xv = randomVector(n, 5),
                              rv = randomVector(n, 6);
        const Eigen::VectorXd dv = randomVector(n, 7).cwiseAbs().array() + 0.5;
        Eigen::VectorXd results[2][3];
        detail::CgSums sums[2];
        int k = 0;
        for (const Device* d : {&ref, &dev}) {
          DeviceVector P = DeviceVector::upload(*d, pv, p), Q = DeviceVector::upload(*d, qv, p),
                       X = DeviceVector::upload(*d, xv, p), R = DeviceVector::upload(*d, rv, p),
                       D = DeviceVector::upload(*d, dv, p);
          sums[k] = detail::cgUpdate(0.3, P, Q, D, X, R);
          detail::cgDirection(0.7, R, D, P);
          results[k][0] = X.download();
          results[k][1] = R.download();
          results[k][2] = P.download();
          ++k;
        }
        const Eigen::VectorXd rNew = rv - 0.3 * qv;
        CHECK(maxDiff(results[1][0], (xv + 0.3 * pv)) <= 4 * tolFor(p));
        CHECK(maxDiff(results[1][1], rNew) <= 4 * tolFor(p));
        const Eigen::VectorXd pNew = dv.cwiseProduct(rNew) + 0.7 * pv;
        CHECK(maxDiff(results[1][2], pNew) <= 8 * tolFor(p));
        const double scale = std::max(1.0, static_cast<double>(n));
        CHECK(std::abs(sums[1].rz - rNew.dot(dv.cwiseProduct(rNew))) <= 8 * tolFor(p) * scale);
        CHECK(std::abs(sums[1].rr - rNew.squaredNorm()) <= 8 * tolFor(p) * scale);
        CHECK(std::abs(sums[0].rr - sums[1].rr) <= 8 * tolFor(p) * scale);
        const double rmax = n > 0 ? rNew.cwiseAbs().maxCoeff() : 0.0;
        CHECK(std::abs(sums[0].rmax - rmax) <= 4 * tolFor(p));
        CHECK(std::abs(sums[1].rmax - rmax) <= 4 * tolFor(p));
        // The variant without a diagonal computes the same x, r, r.r and max|r|.
        DeviceVector P = DeviceVector::upload(dev, pv, p), Q = DeviceVector::upload(dev, qv, p),
                     X = DeviceVector::upload(dev, xv, p), R = DeviceVector::upload(dev, rv, p);
        const detail::CgSums xr = detail::cgUpdateXR(0.3, P, Q, X, R);
        CHECK(maxDiff(R.download(), rNew) <= 4 * tolFor(p));
        CHECK(std::abs(xr.rr - rNew.squaredNorm()) <= 8 * tolFor(p) * scale);
        CHECK(std::abs(xr.rmax - rmax) <= 4 * tolFor(p));
      }
    }
  }

  TEST_CASE("blas1: the STREAM triad kernel agrees with the reference") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    for (const int n : kSizes) {
      CAPTURE(n);
      const Eigen::VectorXd b = randomVector(n, 8), c = randomVector(n, 9);
      for (const Device* d : {static_cast<const Device*>(nullptr), &dev}) {
        const Device use = d != nullptr ? *d : Device::reference();
        DeviceVector A(use, static_cast<std::size_t>(n), Precision::Float);
        detail::triad(A, DeviceVector::upload(use, b, Precision::Float), DeviceVector::upload(use, c, Precision::Float),
                      3.0);
        CHECK(maxDiff(A.download(), b + 3.0 * c) <= 8 * tolFor(Precision::Float));
      }
    }
  }

  TEST_CASE("blas1: mismatched sizes and devices are rejected") {
    const Device ref = Device::reference();
    DeviceVector a(ref, 3, Precision::Double), b(ref, 4, Precision::Double), c(ref, 3, Precision::Float);
    CHECK_THROWS_AS(axpy(1.0, a, b), InvalidArgument);
    CHECK_THROWS_AS((void)dot(a, c), InvalidArgument);
  }
}
