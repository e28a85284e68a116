// CsrMatrix: validation, reference SpMV, diagonal, symmetry check and Eigen conversions.
#include <cmath>
#include <sstream>
#include <string>

#include "duplexfit/error.hpp"
#include "duplexfit/sparse.hpp"

namespace duplexfit {

void CsrMatrix::validate() const {
  auto fail = [](const std::string& what) { throw InvalidArgument("invalid CSR matrix: " + what); };
  if (rows < 0 || cols < 0) fail("negative dimensions");
  if (rowPtr.size() != static_cast<std::size_t>(rows) + 1) {
    fail("rowPtr has " + std::to_string(rowPtr.size()) + " entries, expected rows + 1 = " +
         std::to_string(static_cast<long long>(rows) + 1));
  }
  if (rowPtr[0] != 0) fail("rowPtr[0] is " + std::to_string(rowPtr[0]) + ", expected 0");
  if (colIdx.size() != values.size()) {
    fail("colIdx has " + std::to_string(colIdx.size()) + " entries but values has " +
         std::to_string(values.size()));
  }
  if (static_cast<std::size_t>(rowPtr[static_cast<std::size_t>(rows)]) != values.size()) {
    fail("rowPtr[rows] = " + std::to_string(rowPtr[static_cast<std::size_t>(rows)]) +
         " does not equal the number of values " + std::to_string(values.size()));
  }
  // The row pointers first: non-decreasing from 0 to the number of values, so no entry is read out of range.
  for (Index i = 0; i < rows; ++i) {
    if (rowPtr[static_cast<std::size_t>(i) + 1] < rowPtr[static_cast<std::size_t>(i)]) {
      fail("rowPtr decreases at row " + std::to_string(i));
    }
  }
  // Then the rows' entries, in parallel for the first row that fails (a level system has tens of millions
  // of entries); the loop below starts there, so the message is the one a serial scan gives.
  const auto rowFails = [this](Index i) {
    const Index b = rowPtr[static_cast<std::size_t>(i)], e = rowPtr[static_cast<std::size_t>(i) + 1];
    for (Index k = b; k < e; ++k) {
      const Index c = colIdx[static_cast<std::size_t>(k)];
      if (c < 0 || c >= cols || (k > b && c <= colIdx[static_cast<std::size_t>(k) - 1]) ||
          !std::isfinite(values[static_cast<std::size_t>(k)])) {
        return true;
      }
    }
    return false;
  };
  Index first = rows;
#pragma omp parallel for schedule(static) reduction(min : first)
  for (Index i = 0; i < rows; ++i) {
    if (i < first && rowFails(i)) first = i;
  }
  for (Index i = first; i < rows; ++i) {
    const Index b = rowPtr[static_cast<std::size_t>(i)], e = rowPtr[static_cast<std::size_t>(i) + 1];
    for (Index k = b; k < e; ++k) {
      const Index c = colIdx[static_cast<std::size_t>(k)];
      if (c < 0 || c >= cols) {
        fail("row " + std::to_string(i) + " has column index " + std::to_string(c) + " outside [0, " +
             std::to_string(cols) + ")");
      }
      if (k > b && c <= colIdx[static_cast<std::size_t>(k) - 1]) {
        fail("row " + std::to_string(i) + " has unsorted or repeated column " + std::to_string(c));
      }
      const double v = values[static_cast<std::size_t>(k)];
      if (!std::isfinite(v)) {
        std::ostringstream msg;
        msg << "element (row " << i << ", column " << c << ") is " << v << " (not finite)";
        fail(msg.str());
      }
    }
  }
}

Eigen::VectorXd CsrMatrix::multiply(const Eigen::VectorXd& x) const {
  if (x.size() != cols) {
    throw InvalidArgument("CsrMatrix::multiply: x has " + std::to_string(x.size()) + " entries, matrix has " +
                          std::to_string(cols) + " columns");
  }
  Eigen::VectorXd y(rows);
#pragma omp parallel for schedule(static)
  for (Index i = 0; i < rows; ++i) {
    double s = 0.0;
    for (Index k = rowPtr[static_cast<std::size_t>(i)]; k < rowPtr[static_cast<std::size_t>(i) + 1]; ++k) {
      s += values[static_cast<std::size_t>(k)] * x[colIdx[static_cast<std::size_t>(k)]];
    }
    y[i] = s;
  }
  return y;
}

Eigen::VectorXd CsrMatrix::diagonal() const {
  // Each row from its end: the last entry in column i is the one kept (as a forward scan keeps it, for a
  // matrix not validated), and a symmetric pattern's diagonal is met halfway. Rows in parallel: a level
  // system has tens of millions of entries, and its diagonal is asked for by the upload and the FSAI set-up.
  const Index m = std::min(rows, cols);
  Eigen::VectorXd d = Eigen::VectorXd::Zero(m);
#pragma omp parallel for schedule(static)
  for (Index i = 0; i < m; ++i) {
    for (Index k = rowPtr[static_cast<std::size_t>(i) + 1]; k-- > rowPtr[static_cast<std::size_t>(i)];) {
      if (colIdx[static_cast<std::size_t>(k)] == i) {
        d[i] = values[static_cast<std::size_t>(k)];
        break;
      }
    }
  }
  return d;
}

bool CsrMatrix::isSymmetric(double tol) const {
  if (rows != cols) return false;
  const auto a = toEigen();
  const Eigen::SparseMatrix<double, Eigen::RowMajor, Index> t = a.transpose();
  double maxAbs = 0.0;
  for (double v : values) maxAbs = std::max(maxAbs, std::abs(v));
  const Eigen::SparseMatrix<double, Eigen::RowMajor, Index> diff = a - t;
  for (Index k = 0; k < diff.nonZeros(); ++k) {
    if (std::abs(diff.valuePtr()[k]) > tol * maxAbs) return false;
  }
  return true;
}

Eigen::SparseMatrix<double, Eigen::RowMajor, Index> CsrMatrix::toEigen() const {
  Eigen::SparseMatrix<double, Eigen::RowMajor, Index> m(rows, cols);
  m.resizeNonZeros(static_cast<Index>(values.size()));
  std::copy(rowPtr.begin(), rowPtr.end(), m.outerIndexPtr());
  std::copy(colIdx.begin(), colIdx.end(), m.innerIndexPtr());
  std::copy(values.begin(), values.end(), m.valuePtr());
  return m;
}

CsrMatrix CsrMatrix::fromEigen(const Eigen::SparseMatrix<double, Eigen::RowMajor, Index>& input) {
  Eigen::SparseMatrix<double, Eigen::RowMajor, Index> m = input;
  m.makeCompressed();
  CsrMatrix a;
  a.rows = static_cast<Index>(m.rows());
  a.cols = static_cast<Index>(m.cols());
  a.rowPtr.assign(m.outerIndexPtr(), m.outerIndexPtr() + m.rows() + 1);
  a.colIdx.assign(m.innerIndexPtr(), m.innerIndexPtr() + m.nonZeros());
  a.values.assign(m.valuePtr(), m.valuePtr() + m.nonZeros());
  return a;
}

}  // namespace duplexfit
