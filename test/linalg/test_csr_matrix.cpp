// CsrMatrix validation, reference SpMV and Eigen conversions.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/sparse.hpp"
#include "shapes.hpp"

using namespace duplexfit;

namespace {
CsrMatrix csr(Index rows, Index cols, std::vector<Index> rowPtr, std::vector<Index> colIdx, std::vector<double> values) {
  CsrMatrix a;
  a.rows = rows;
  a.cols = cols;
  a.rowPtr = std::move(rowPtr);
  a.colIdx = std::move(colIdx);
  a.values = std::move(values);
  return a;
}

CsrMatrix small() { return csr(3, 3, {0, 2, 3, 5}, {0, 2, 1, 0, 2}, {4.0, 1.0, 3.0, 1.0, 5.0}); }

std::string validationMessage(const CsrMatrix& a) {
  try {
    a.validate();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return {};
}
}  // namespace

TEST_SUITE("linalg") {
  TEST_CASE("csr: validate accepts a well-formed matrix and names the offending element otherwise") {
    CHECK_NOTHROW(small().validate());
    CsrMatrix nan = small();
    nan.values[3] = std::numeric_limits<double>::quiet_NaN();
    const std::string msg = validationMessage(nan);
    CHECK(msg.find("row 2") != std::string::npos);
    CHECK(msg.find("column 0") != std::string::npos);
    CsrMatrix inf = small();
    inf.values[1] = std::numeric_limits<double>::infinity();
    CHECK(validationMessage(inf).find("row 0, column 2") != std::string::npos);
    CsrMatrix unsorted = small();
    std::swap(unsorted.colIdx[0], unsorted.colIdx[1]);
    CHECK(validationMessage(unsorted).find("row 0") != std::string::npos);
    CsrMatrix range = small();
    range.colIdx[2] = 3;
    CHECK(validationMessage(range).find("outside") != std::string::npos);
    CsrMatrix ptr = small();
    ptr.rowPtr[3] = 4;
    CHECK(!validationMessage(ptr).empty());
    CHECK_NOTHROW(CsrMatrix{}.validate());
    // A row pointer past the values before a decrease: reported without reading beyond them (ASan).
    CsrMatrix jump = small();
    jump.rowPtr = {0, 9, 2, 5};
    CHECK(validationMessage(jump).find("rowPtr decreases at row 1") != std::string::npos);
  }

  TEST_CASE("csr: validate names the first bad row of a large matrix (rows checked in parallel)") {
    const Index n = 200000;
    CsrMatrix a;
    a.rows = a.cols = n;
    a.rowPtr.resize(static_cast<std::size_t>(n) + 1);
    for (Index i = 0; i < n; ++i) {
      a.rowPtr[static_cast<std::size_t>(i)] = static_cast<Index>(a.colIdx.size());
      for (Index j = std::max<Index>(0, i - 1); j <= std::min<Index>(n - 1, i + 1); ++j) {
        a.colIdx.push_back(j);
        a.values.push_back(j == i ? 4.0 : -1.0);
      }
    }
    a.rowPtr.back() = static_cast<Index>(a.colIdx.size());
    CHECK_NOTHROW(a.validate());
    CsrMatrix bad = a;
    bad.values[static_cast<std::size_t>(bad.rowPtr[190000])] = std::numeric_limits<double>::quiet_NaN();
    bad.colIdx[static_cast<std::size_t>(bad.rowPtr[150001]) + 1] = n;  // out of range, the earlier defect
    CHECK(validationMessage(bad).find("row 150001 has column index") != std::string::npos);
    bad.colIdx[static_cast<std::size_t>(bad.rowPtr[3]) + 1] = 2;  // row 3's columns 2, 3, 4 become 2, 2, 4
    CHECK(validationMessage(bad).find("row 3 has unsorted or repeated column 2") != std::string::npos);
  }

  TEST_CASE("csr: multiply, diagonal, symmetry and Eigen round trip") {
    const CsrMatrix a = small();
    Eigen::VectorXd x(3);
    x << 1.0, -2.0, 0.5;
    const Eigen::VectorXd y = a.multiply(x);
    CHECK(y[0] == doctest::Approx(4.5));
    CHECK(y[1] == doctest::Approx(-6.0));
    CHECK(y[2] == doctest::Approx(3.5));
    CHECK((a.toEigen() * x - y).norm() < 1e-14);
    CHECK(a.diagonal()[2] == 5.0);
    CHECK(a.diagonal() == Eigen::Vector3d(4.0, 3.0, 5.0));
    // Not validated: a row without its diagonal gives 0, a repeated diagonal entry its last value.
    const CsrMatrix odd = csr(3, 4, {0, 3, 4, 5}, {0, 2, 0, 3, 2}, {1.0, 7.0, 2.0, 9.0, 6.0});
    CHECK(odd.diagonal() == Eigen::Vector3d(2.0, 0.0, 6.0));
    CHECK(a.isSymmetric());
    CsrMatrix b = a;
    b.values[1] = 2.0;
    CHECK_FALSE(b.isSymmetric());
    const CsrMatrix c = CsrMatrix::fromEigen(a.toEigen());
    CHECK(c.rowPtr == a.rowPtr);
    CHECK(c.colIdx == a.colIdx);
    CHECK(c.values == a.values);
    CHECK_THROWS_AS(a.multiply(Eigen::VectorXd(2)), InvalidArgument);
  }

  TEST_CASE("csr: random SPD matrices are symmetric and valid for n = 0, 1 and larger") {
    for (const int n : {0, 1, 2, 65, 1000}) {
      CAPTURE(n);
      const CsrMatrix a = testing::randomSpdMatrix(n, 12, 7u);
      CHECK(a.rows == n);
      CHECK_NOTHROW(a.validate());
      CHECK(a.isSymmetric());
    }
  }
}
