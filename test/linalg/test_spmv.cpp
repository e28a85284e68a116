// SpMV kernels (row per work-item, row per group, fused SpMV + dot) against the reference and against
// double-precision CsrMatrix::multiply, on random SPD and on Wendland matrices.
#include <doctest/doctest.h>

#include <random>

#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/wendland.hpp"
#include "linalg/ops.hpp"
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

// |y − A x|_i ≤ tol · (|A| |x|)_i + tiny, elementwise: the standard SpMV error bound.
void checkSpmvResult(const CsrMatrix& a, const Eigen::VectorXd& x, const Eigen::VectorXd& y, double tol) {
  const Eigen::VectorXd exact = a.multiply(x);
  CsrMatrix absA = a;
  for (double& v : absA.values) v = std::abs(v);
  const Eigen::VectorXd bound = absA.multiply(x.cwiseAbs());
  int bad = 0;
  for (Eigen::Index i = 0; i < exact.size(); ++i) {
    if (std::abs(y[i] - exact[i]) > tol * bound[i] + 1e-300) ++bad;
  }
  CHECK(bad == 0);
}

void runAll(const Device& dev, const CsrMatrix& a, unsigned seed) {
  const Device ref = Device::reference();
  const Eigen::VectorXd x = randomVector(a.cols, seed);
  for (const Precision p : {Precision::Float, Precision::Double}) {
    if (p == Precision::Double && !dev.supportsDouble()) continue;
    CAPTURE(precisionName(p));
    const double tol = p == Precision::Double ? 1e-13 : 5e-6;
    for (const Device* d : {&ref, &dev}) {
      const DeviceCsr m = DeviceCsr::upload(*d, a, p);
      CHECK(m.nonZeros() == a.nonZeros());
      const DeviceVector dx = DeviceVector::upload(*d, x, p);
      for (const SpmvKernel k : {SpmvKernel::Auto, SpmvKernel::RowPerItem, SpmvKernel::RowPerGroup}) {
        CAPTURE(static_cast<int>(k));
        DeviceVector y(*d, static_cast<std::size_t>(a.rows), p);
        y.fill(std::numeric_limits<double>::quiet_NaN());
        spmv(m, dx, y, k);
        checkSpmvResult(a, x, y.download(), tol);
        if (a.rows == a.cols) {
          DeviceVector y2(*d, static_cast<std::size_t>(a.rows), p);
          const double pq = detail::spmvDot(m, dx, y2, k);
          checkSpmvResult(a, x, y2.download(), tol);
          const double exact = x.dot(a.multiply(x));
          CHECK(std::abs(pq - exact) <= tol * 10 * (1.0 + x.squaredNorm() * 10));
        }
      }
    }
  }
}

}  // namespace

TEST_SUITE("linalg") {
  TEST_CASE("spmv: OpenCL matches the reference on random SPD CSR of awkward sizes") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    for (const int n : {0, 1, 2, 63, 64, 65, 257, 1000, 10007}) {
      CAPTURE(n);
      runAll(dev, testing::randomSpdMatrix(n, 20, static_cast<std::uint32_t>(n) + 11u), 3u);
    }
  }

  TEST_CASE("spmv: OpenCL matches the reference on Wendland matrices of a sampled sphere and torus") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    for (const auto shape : {testing::Shape::Sphere, testing::Shape::Torus}) {
      const int n = 3001;
      const double sigma = testing::sigmaForNonZeros(shape, n, 0.05, 45.0);
      const testing::LevelCentres c = testing::levelCentres(shape, n, 0.05, sigma);
      const CsrMatrix a = assembleWendland(c.centres, sigma);
      CHECK(a.rows == 3 * n);
      runAll(dev, a, 9u);
    }
  }

  TEST_CASE("spmv: a matrix with rows but no stored entries gives zeros") {
    CsrMatrix a;
    a.rows = 5;
    a.cols = 5;
    a.rowPtr.assign(6, 0);
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    for (const Device& d : devices) {
      const DeviceCsr m = DeviceCsr::upload(d, a, Precision::Float);
      DeviceVector x = DeviceVector::upload(d, Eigen::VectorXd::Ones(5), Precision::Float);
      DeviceVector y(d, 5, Precision::Float);
      y.fill(7.0);
      spmv(m, x, y);
      CHECK(y.download().cwiseAbs().maxCoeff() == 0.0);
    }
  }

  TEST_CASE("spmv: an upload into a recycled matrix's buffers gives the same products as a fresh one") {
    // A fit's levels: a large matrix, then a smaller one into its buffers, then a larger one (the buffers
    // too small: released, new ones made), then one whose recycled matrix is on another device.
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    for (const Device& d : devices) {
      CAPTURE(d.info().spec);
      DeviceCsr held;
      for (const int n : {3000, 1200, 5000}) {
        const CsrMatrix a = testing::randomSpdMatrix(n, 20, static_cast<std::uint32_t>(n));
        const Eigen::VectorXd x = randomVector(n, 5u);
        DeviceCsr m = DeviceCsr::upload(d, a, Precision::Float, std::move(held));
        CHECK(held.nonZeros() == 0);
        CHECK(m.nonZeros() == a.nonZeros());
        const DeviceCsr fresh = DeviceCsr::upload(d, a, Precision::Float);
        const DeviceVector dx = DeviceVector::upload(d, x, Precision::Float);
        DeviceVector y(d, static_cast<std::size_t>(n), Precision::Float), yFresh(d, static_cast<std::size_t>(n), Precision::Float);
        y.fill(std::numeric_limits<double>::quiet_NaN());
        spmv(m, dx, y);
        spmv(fresh, dx, yFresh);
        CHECK(y.download() == yFresh.download());
        checkSpmvResult(a, x, y.download(), 5e-6);
        held = std::move(m);
      }
      const CsrMatrix small = testing::randomSpdMatrix(100, 5, 2u);
      const DeviceCsr other = DeviceCsr::upload(Device::reference(), small, Precision::Float, std::move(held));
      CHECK(other.nonZeros() == small.nonZeros());
      CHECK(other.device().isReference());
    }
  }

  TEST_CASE("spmv: non-finite matrices are rejected at upload, naming the element") {
    CsrMatrix a = testing::randomSpdMatrix(50, 5, 1u);
    a.values[17] = std::numeric_limits<double>::infinity();
    try {
      (void)DeviceCsr::upload(Device::reference(), a, Precision::Double);
      FAIL("expected InvalidArgument");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("row") != std::string::npos);
      CHECK(std::string(e.what()).find("inf") != std::string::npos);
    }
  }
}
