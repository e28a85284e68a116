// The Wendland basis and assembleWendland against a dense brute-force build on level centres, plus
// sanity checks of the generated test shapes and random SPD matrices (test/support/shapes.hpp).
#include <doctest/doctest.h>

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/wendland.hpp"
#include "device/device_impl.hpp"
#include "duplexfit/linalg.hpp"
#include "field/wendland_detail.hpp"
#include "linalg/storage.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

namespace {

using duplexfit::CsrMatrix;
using duplexfit::Index;
using duplexfit::InvalidArgument;
using duplexfit::Points;
using duplexfit::wendland;
using duplexfit::testing::LevelCentres;
using duplexfit::testing::Shape;

Eigen::MatrixXd toDense(const CsrMatrix& a) {
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(a.rows, a.cols);
  for (Index i = 0; i < a.rows; ++i) {
    for (Index k = a.rowPtr[static_cast<std::size_t>(i)];
         k < a.rowPtr[static_cast<std::size_t>(i) + 1]; ++k) {
      d(i, a.colIdx[static_cast<std::size_t>(k)]) += a.values[static_cast<std::size_t>(k)];
    }
  }
  return d;
}

/// Φ + λI built densely from the definition (entries with ‖c_i − c_j‖ < σ).
Eigen::MatrixXd bruteForce(const Points& c, double sigma, double lambda, Eigen::MatrixXi* pattern) {
  const Eigen::Index n = c.rows();
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(n, n);
  *pattern = Eigen::MatrixXi::Zero(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      const double r = (c.row(i) - c.row(j)).norm();
      if (r < sigma) {
        d(i, j) = i == j ? 1.0 + lambda : wendland(r / sigma);
        (*pattern)(i, j) = 1;
      }
    }
  }
  return d;
}

double meanRowNonZeros(const CsrMatrix& a) {
  return a.rows == 0 ? 0.0 : static_cast<double>(a.nonZeros()) / static_cast<double>(a.rows);
}

void requireSortedColumns(const CsrMatrix& a) {
  REQUIRE(a.rowPtr.size() == static_cast<std::size_t>(a.rows) + 1);
  REQUIRE(a.rowPtr.front() == 0);
  REQUIRE(static_cast<std::size_t>(a.rowPtr.back()) == a.nonZeros());
  REQUIRE(a.colIdx.size() == a.nonZeros());
  for (Index i = 0; i < a.rows; ++i) {
    const auto b = static_cast<std::size_t>(a.rowPtr[static_cast<std::size_t>(i)]);
    const auto e = static_cast<std::size_t>(a.rowPtr[static_cast<std::size_t>(i) + 1]);
    REQUIRE(b <= e);
    for (std::size_t k = b + 1; k < e; ++k) REQUIRE(a.colIdx[k - 1] < a.colIdx[k]);
  }
}

}  // namespace

TEST_SUITE("field") {
  TEST_CASE("wendland: values at 0 and 1, zero beyond the support, derivative") {
    CHECK(wendland(0.0) == 1.0);
    CHECK(wendland(1.0) == 0.0);
    CHECK(wendland(1.5) == 0.0);
    CHECK(wendland(0.5) == doctest::Approx(0.0625 * 3.0));
    CHECK(duplexfit::wendlandDerivative(0.0) == 0.0);
    CHECK(duplexfit::wendlandDerivative(1.0) == 0.0);
    const double h = 1e-6;
    for (double r : {0.05, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95, 0.999}) {
      CAPTURE(r);
      const double central = (wendland(r + h) - wendland(r - h)) / (2.0 * h);
      CHECK(duplexfit::wendlandDerivative(r) == doctest::Approx(central).epsilon(1e-6).scale(1.0));
      CHECK(wendland(r) > 0.0);
      CHECK(wendland(r) < 1.0);
      const double second = (duplexfit::wendlandDerivative(r + h) - duplexfit::wendlandDerivative(r - h)) / (2.0 * h);
      CHECK(duplexfit::wendlandSecondDerivative(r) == doctest::Approx(second).epsilon(1e-6).scale(1.0));
    }
    CHECK(duplexfit::wendlandSecondDerivative(0.0) == -20.0);
    CHECK(duplexfit::wendlandSecondDerivative(1.0) == 0.0);
  }

  TEST_CASE("wendland: the assembly on the cell grid and on the k-d tree give the same matrix") {
    // A sphere's level centres plus duplicates, points on cell boundaries (multiples of sigma) and a
    // far-away one: the grid (cells of sigma) and the tree must find the same neighbours at the same
    // distances, so the matrices agree bit for bit.
    const double sigma = 0.12;
    Points centres = duplexfit::testing::fibonacciSphere(3000, 0.5);
    const Eigen::Index base = centres.rows();
    centres.conservativeResize(base + 40, 3);
    for (Eigen::Index i = 0; i < 20; ++i) centres.row(base + i) = centres.row(7 * i);  // duplicates
    for (Eigen::Index i = 20; i < 39; ++i) {
      centres.row(base + i) << sigma * static_cast<double>(i % 5 - 2), sigma * static_cast<double>(i % 3 - 1), 0.5 - sigma;
    }
    centres.row(base + 39) << 40.0, -3.0, 2.0;
    for (const double lambda : {0.0, 0.3}) {
      const duplexfit::CsrMatrix tree = duplexfit::detail::assembleWendland(centres, sigma, lambda, {}, nullptr, 0);
      const duplexfit::CsrMatrix grid = duplexfit::detail::assembleWendland(centres, sigma, lambda, {}, nullptr);
      const duplexfit::CsrMatrix pub = duplexfit::assembleWendland(centres, sigma, lambda);
      CHECK(tree.nonZeros() > 20 * centres.rows());
      CHECK(grid.rows == tree.rows);
      CHECK(grid.rowPtr == tree.rowPtr);
      CHECK(grid.colIdx == tree.colIdx);
      CHECK(grid.values == tree.values);
      CHECK(pub.values == grid.values);
    }
    // Into the arrays of an earlier matrix (a fit's previous level): the same matrix, on both paths,
    // whether those arrays are larger (kept) or smaller (grown) than needed; the earlier one is left empty.
    for (const std::size_t cells : {duplexfit::detail::CellGrid::kDefaultMaxCells, std::size_t{0}}) {
      duplexfit::CsrMatrix held = duplexfit::assembleWendland(centres, 1.5 * sigma, 0.0);  // more non-zeros
      const std::size_t capacity = held.colIdx.capacity();
      const duplexfit::CsrMatrix expected = duplexfit::assembleWendland(centres, sigma, 0.3);
      duplexfit::CsrMatrix got = duplexfit::detail::assembleWendland(centres, sigma, 0.3, {}, nullptr, cells, &held);
      CHECK(held.nonZeros() == 0);
      CHECK(held.rows == 0);
      CHECK(held.rowPtr == duplexfit::CsrMatrix{}.rowPtr);
      CHECK(got.colIdx.capacity() == capacity);  // the larger arrays were kept
      CHECK(got.rowPtr == expected.rowPtr);
      CHECK(got.colIdx == expected.colIdx);
      CHECK(got.values == expected.values);
      const duplexfit::CsrMatrix wider = duplexfit::assembleWendland(centres, 2.0 * sigma, 0.0);
      const duplexfit::CsrMatrix grown = duplexfit::detail::assembleWendland(centres, 2.0 * sigma, 0.0, {}, nullptr, cells, &got);
      CHECK(grown.colIdx == wider.colIdx);
      CHECK(grown.values == wider.values);
    }
    // The far-away centre is alone in its row; the table then spans it (some 200k cells, usable).
    CHECK(duplexfit::detail::CellGrid(centres, sigma).usable());
    CHECK_FALSE(duplexfit::detail::CellGrid(centres, sigma, 1000).usable());
  }

  TEST_CASE("wendland: the assembly on the device gives the host's matrix bit for bit") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    if (!duplexfit::detail::deviceAssemblyAvailable(dev)) DUPLEXFIT_SKIP("the OpenCL device has no double precision");
    // The grid-against-tree centres (duplicates, centres on cell boundaries, a far-away one) at two supports:
    // about 30 entries a row, and over 100 (beyond the host's insertion-sort cut-off).
    Points centres = duplexfit::testing::fibonacciSphere(3000, 0.5);
    const Eigen::Index base = centres.rows();
    centres.conservativeResize(base + 40, 3);
    for (Eigen::Index i = 0; i < 20; ++i) centres.row(base + i) = centres.row(7 * i);
    for (Eigen::Index i = 20; i < 39; ++i) {
      centres.row(base + i) << 0.12 * static_cast<double>(i % 5 - 2), 0.12 * static_cast<double>(i % 3 - 1), 0.38;
    }
    centres.row(base + 39) << 40.0, -3.0, 2.0;
    const auto deviceArrays = [&dev](const duplexfit::DeviceCsr& m, std::vector<Index>& rowPtr, std::vector<Index>& col,
                                     std::vector<double>& val) {
      const duplexfit::detail::CsrStorage& st = m.storage();
      auto& queue = dev.impl()->queue();
      rowPtr.resize(st.rows + 1);
      col.resize(st.nnz);
      REQUIRE(queue.enqueueReadBuffer(st.rowPtrBuf, CL_TRUE, 0, rowPtr.size() * sizeof(Index), rowPtr.data()) == CL_SUCCESS);
      REQUIRE(queue.enqueueReadBuffer(st.colBuf, CL_TRUE, 0, col.size() * sizeof(Index), col.data()) == CL_SUCCESS);
      if (m.precision() == duplexfit::Precision::Double) {
        val.resize(st.nnz);
        REQUIRE(queue.enqueueReadBuffer(st.valBuf, CL_TRUE, 0, val.size() * sizeof(double), val.data()) == CL_SUCCESS);
      } else {
        std::vector<float> f(st.nnz);
        REQUIRE(queue.enqueueReadBuffer(st.valBuf, CL_TRUE, 0, f.size() * sizeof(float), f.data()) == CL_SUCCESS);
        val.assign(f.begin(), f.end());
      }
    };
    std::size_t nnzChecked = 0;
    for (const double sigma : {0.12, 0.25}) {
      for (const duplexfit::Precision precision : {duplexfit::Precision::Float, duplexfit::Precision::Double}) {
        CAPTURE(sigma);
        CAPTURE(duplexfit::precisionName(precision));
        const CsrMatrix expected = duplexfit::assembleWendland(centres, sigma, 0.3);
        std::size_t budgetAsked = 0;
        duplexfit::detail::DeviceAssembly got = duplexfit::detail::assembleOnDevice(
            dev, precision, centres, sigma, 0.3, [&budgetAsked](std::size_t nz) { budgetAsked = nz; });
        REQUIRE(got.onDevice);
        CHECK(budgetAsked == expected.nonZeros());  // the exact count, before the matrix's buffers exist
        CHECK(got.host.rows == expected.rows);
        CHECK(got.host.rowPtr == expected.rowPtr);
        CHECK(got.host.colIdx == expected.colIdx);
        CHECK(got.host.values == expected.values);
        CHECK(got.device.rows() == static_cast<std::size_t>(expected.rows));
        CHECK(got.device.precision() == precision);
        CHECK(got.device.diagonal() == expected.diagonal());
        std::vector<Index> rowPtr, col;
        std::vector<double> val;
        deviceArrays(got.device, rowPtr, col, val);
        CHECK(rowPtr == expected.rowPtr);
        CHECK(col == expected.colIdx);
        // As an upload rounds the host's values.
        const duplexfit::DeviceCsr uploaded = duplexfit::DeviceCsr::upload(dev, expected, precision);
        std::vector<Index> upRowPtr, upCol;
        std::vector<double> upVal;
        deviceArrays(uploaded, upRowPtr, upCol, upVal);
        CHECK(val == upVal);
        nnzChecked += expected.nonZeros();
      }
    }
    CHECK(nnzChecked > 4 * 60 * 3000);
    // Into the arrays and buffers of an earlier level: the same matrix, the earlier one left empty.
    duplexfit::detail::DeviceAssembly held =
        duplexfit::detail::assembleOnDevice(dev, duplexfit::Precision::Float, centres, 0.25, 0.0, {});
    duplexfit::detail::DeviceAssembly again = duplexfit::detail::assembleOnDevice(
        dev, duplexfit::Precision::Float, centres, 0.12, 0.3, {}, nullptr, duplexfit::detail::CellGrid::kDefaultMaxCells,
        &held.host, &held.device);
    CHECK(held.host.nonZeros() == 0);
    CHECK(held.device.rows() == 0);
    CHECK(again.host.values == duplexfit::assembleWendland(centres, 0.12, 0.3).values);
    // Where the grid's table is too large, the host assembles and uploads: the same matrix.
    const duplexfit::detail::DeviceAssembly tree =
        duplexfit::detail::assembleOnDevice(dev, duplexfit::Precision::Float, centres, 0.12, 0.3, {}, nullptr, 1000);
    CHECK_FALSE(tree.onDevice);
    CHECK(tree.host.values == again.host.values);
    // Double values beyond one buffer of the device (a cap of 3 MiB: 4.6 MB of them, 2.3 MB as floats): the
    // host assembles and uploads the float system.
    duplexfit::DeviceOptions small;
    small.maxAllocBytes = 3u << 20;
    const duplexfit::Device capped = duplexfit::Device::open(dev.info().spec, small);
    const CsrMatrix wide = duplexfit::assembleWendland(centres, 0.25, 0.3);
    REQUIRE(wide.nonZeros() * sizeof(double) > small.maxAllocBytes);
    REQUIRE(wide.nonZeros() * sizeof(float) <= small.maxAllocBytes);
    const duplexfit::detail::DeviceAssembly fallback =
        duplexfit::detail::assembleOnDevice(capped, duplexfit::Precision::Float, centres, 0.25, 0.3, {});
    CHECK_FALSE(fallback.onDevice);
    CHECK(fallback.host.values == wide.values);
    CHECK(fallback.device.nonZeros() == wide.nonZeros());
    // The reference device has no kernels: its assembly is the host's.
    const duplexfit::detail::DeviceAssembly ref = duplexfit::detail::assembleOnDevice(
        duplexfit::Device::reference(), duplexfit::Precision::Float, centres, 0.12, 0.3, {});
    CHECK_FALSE(ref.onDevice);
    CHECK(ref.host.values == again.host.values);
    // A budget that refuses the count stops before the matrix's buffers exist.
    CHECK_THROWS_AS(duplexfit::detail::assembleOnDevice(dev, duplexfit::Precision::Float, centres, 0.12, 0.3,
                                                        [](std::size_t) { throw std::runtime_error("over budget"); }),
                    std::runtime_error);
    // Bad centres are named.
    Points bad = centres;
    bad(17, 1) = std::nan("");
    CHECK_THROWS_WITH_AS(duplexfit::detail::assembleOnDevice(dev, duplexfit::Precision::Float, bad, 0.12, 0.3, {}),
                         doctest::Contains("row 17"), InvalidArgument);
  }

  TEST_CASE("wendland: assembly equals a dense brute-force build on sphere level centres") {
    const double delta = 0.02;
    const int n = 200;
    // 30 non-zeros a row, and 100 (rows longer than the insertion-sort cut-off of the assembly).
    for (const std::pair<double, double>& params :
         {std::pair{30.0, 0.0}, std::pair{30.0, 0.25}, std::pair{100.0, 0.0}}) {
      const double target = params.first;
      const double lambda = params.second;
      CAPTURE(target);
      CAPTURE(lambda);
      const double sigma = duplexfit::testing::sigmaForNonZeros(Shape::Sphere, n, delta, target);
      const LevelCentres level = duplexfit::testing::levelCentres(Shape::Sphere, n, delta, sigma);
      const CsrMatrix a = duplexfit::assembleWendland(level.centres, sigma, lambda);
      REQUIRE(a.rows == 3 * n);
      REQUIRE(a.cols == 3 * n);
      requireSortedColumns(a);
      a.validate();

      Eigen::MatrixXi pattern;
      const Eigen::MatrixXd want = bruteForce(level.centres, sigma, lambda, &pattern);
      const Eigen::MatrixXd got = toDense(a);
      CHECK((got - want).cwiseAbs().maxCoeff() <= 1e-14);
      CHECK(got == got.transpose());
      CHECK(got.diagonal().isConstant(1.0 + lambda));
      // Same pattern row by row, allowing only entries that sit on the support boundary to differ.
      for (Index i = 0; i < a.rows; ++i) {
        const Index count =
            a.rowPtr[static_cast<std::size_t>(i) + 1] - a.rowPtr[static_cast<std::size_t>(i)];
        CHECK(std::abs(count - pattern.row(i).sum()) <= 1);
        REQUIRE(count >= 1);
        REQUIRE(count <= 3 * n);
      }
      CHECK(meanRowNonZeros(a) == doctest::Approx(target).epsilon(0.2));
      if (lambda == 0.0) CHECK(Eigen::LLT<Eigen::MatrixXd>(got).info() == Eigen::Success);
    }
  }

  TEST_CASE("wendland: torus level system is symmetric positive definite") {
    const double sigma = duplexfit::testing::sigmaForNonZeros(Shape::Torus, 150, 0.03, 40.0);
    const LevelCentres level = duplexfit::testing::levelCentres(Shape::Torus, 150, 0.03, sigma);
    const CsrMatrix a = duplexfit::assembleWendland(level.centres, sigma);
    requireSortedColumns(a);
    const Eigen::MatrixXd dense = toDense(a);
    CHECK(dense == dense.transpose());
    CHECK(Eigen::LLT<Eigen::MatrixXd>(dense).info() == Eigen::Success);
    CHECK(meanRowNonZeros(a) == doctest::Approx(40.0).epsilon(0.2));
  }

  TEST_CASE("wendland: empty, single and duplicated centres") {
    const CsrMatrix empty = duplexfit::assembleWendland(Points(0, 3), 0.1);
    CHECK(empty.rows == 0);
    CHECK(empty.cols == 0);
    CHECK(empty.rowPtr == std::vector<Index>{0});
    CHECK(empty.nonZeros() == 0);

    Points one(1, 3);
    one << 0.1, 0.2, 0.3;
    const CsrMatrix single = duplexfit::assembleWendland(one, 0.5, 0.5);
    CHECK(single.rows == 1);
    CHECK(single.rowPtr == std::vector<Index>{0, 1});
    CHECK(single.colIdx == std::vector<Index>{0});
    CHECK(single.values == std::vector<double>{1.5});

    // Duplicates are assembled faithfully (a singular matrix: the caller merges them, §3.5).
    Points twice(3, 3);
    twice << 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0;
    const CsrMatrix dup = duplexfit::assembleWendland(twice, 1.0);
    CHECK(dup.rowPtr == std::vector<Index>{0, 2, 4, 5});
    CHECK(dup.colIdx == std::vector<Index>{0, 1, 0, 1, 2});
    CHECK(dup.values == std::vector<double>{1.0, 1.0, 1.0, 1.0, 1.0});
  }

  TEST_CASE("wendland: invalid arguments throw InvalidArgument") {
    const Points c = duplexfit::testing::fibonacciSphere(20, 0.5);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    for (double sigma : {0.0, -0.1, nan, inf}) {
      CAPTURE(sigma);
      CHECK_THROWS_AS(duplexfit::assembleWendland(c, sigma), InvalidArgument);
    }
    for (double lambda : {-1e-12, -1.0, nan, inf}) {
      CAPTURE(lambda);
      CHECK_THROWS_AS(duplexfit::assembleWendland(c, 0.3, lambda), InvalidArgument);
    }
    Points bad = c;
    bad(17, 2) = nan;
    try {
      (void)duplexfit::assembleWendland(bad, 0.3);
      FAIL("a NaN centre was accepted");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("row 17") != std::string::npos);
    }
  }

  TEST_CASE("shapes: sphere and torus samples, level centres and sigma for a row density") {
    const double delta = 0.03;
    const double sigma = 0.1;
    Points normals;
    const Points sphere = duplexfit::testing::fibonacciSphere(500, 0.5, &normals);
    REQUIRE(sphere.rows() == 500);
    for (Eigen::Index i = 0; i < sphere.rows(); ++i) {
      REQUIRE(sphere.row(i).norm() == doctest::Approx(0.5).epsilon(1e-14));
      REQUIRE(normals.row(i).norm() == doctest::Approx(1.0).epsilon(1e-14));
      REQUIRE((normals.row(i) - 2.0 * sphere.row(i)).norm() < 1e-14);
    }

    const LevelCentres level = duplexfit::testing::levelCentres(Shape::Sphere, 500, delta, sigma);
    REQUIRE(level.centres.rows() == 1500);
    CHECK(level.surface == 500);
    CHECK(level.offset == 500);
    CHECK(level.offSurface == 500);
    CHECK(level.sigma == sigma);
    for (Eigen::Index i = 0; i < 500; ++i) {
      REQUIRE(level.centres.row(i) == sphere.row(i));
      REQUIRE(level.centres.row(500 + i).norm() == doctest::Approx(0.5 - delta).epsilon(1e-14));
      REQUIRE(level.centres.row(1000 + i).norm() ==
              doctest::Approx(0.5 + sigma / 10).epsilon(1e-14));
    }

    const Points torus = duplexfit::testing::sampledTorus(800, 0.3, 0.15, &normals);
    REQUIRE(torus.rows() == 800);
    double meanZ2 = 0.0;
    for (Eigen::Index i = 0; i < torus.rows(); ++i) {
      const double ring = std::hypot(torus(i, 0), torus(i, 1));
      REQUIRE(std::hypot(ring - 0.3, torus(i, 2)) == doctest::Approx(0.15).epsilon(1e-12));
      REQUIRE(normals.row(i).norm() == doctest::Approx(1.0).epsilon(1e-12));
      // The outward normal points away from the tube's centre circle.
      const Eigen::RowVector3d centre(0.3 * torus(i, 0) / ring, 0.3 * torus(i, 1) / ring, 0.0);
      REQUIRE((torus.row(i) - centre - 0.15 * normals.row(i)).norm() < 1e-12);
      meanZ2 += torus(i, 2) * torus(i, 2) / 800.0;
    }
    // Area-uniform: E[z²] = r²/2 for the tube angle weighted by R + r cos v (the cos term cancels).
    CHECK(meanZ2 == doctest::Approx(0.15 * 0.15 / 2).epsilon(0.02));
    CHECK(duplexfit::testing::fibonacciSphere(0, 1.0).rows() == 0);
    CHECK(duplexfit::testing::sampledTorus(0, 0.3, 0.15).rows() == 0);

    for (Shape shape : {Shape::Sphere, Shape::Torus}) {
      for (double target : {20.0, 45.0}) {
        CAPTURE(target);
        const double s = duplexfit::testing::sigmaForNonZeros(shape, 2000, delta, target);
        const LevelCentres c = duplexfit::testing::levelCentres(shape, 2000, delta, s);
        const CsrMatrix a = duplexfit::assembleWendland(c.centres, s);
        CHECK(meanRowNonZeros(a) == doctest::Approx(target).epsilon(0.2));
      }
    }
  }

  TEST_CASE("shapes: random SPD matrices are symmetric, sorted and diagonally dominant") {
    for (int n : {0, 1, 2, 7, 500}) {
      CAPTURE(n);
      const CsrMatrix a = duplexfit::testing::randomSpdMatrix(n, 9, 1234u);
      REQUIRE(a.rows == n);
      REQUIRE(a.cols == n);
      requireSortedColumns(a);
      a.validate();
      const Eigen::MatrixXd d = toDense(a);
      CHECK(d == d.transpose());
      for (Index i = 0; i < n; ++i) {
        const double off = d.row(i).cwiseAbs().sum() - std::abs(d(i, i));
        REQUIRE(d(i, i) > off);
      }
      if (n > 0) CHECK(Eigen::LLT<Eigen::MatrixXd>(d).info() == Eigen::Success);
      if (n == 500) CHECK(meanRowNonZeros(a) == doctest::Approx(9.0).epsilon(0.1));
      if (n == 1) CHECK(a.nonZeros() == 1);
      // The same seed gives the same matrix.
      const CsrMatrix b = duplexfit::testing::randomSpdMatrix(n, 9, 1234u);
      CHECK(a.colIdx == b.colIdx);
      CHECK(a.values == b.values);
    }
  }
}
