// Host-side compressed sparse row matrix: the exchange format between assembly, the device upload and
// the reference path.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "duplexfit/types.hpp"

namespace duplexfit {

/// A square or rectangular CSR matrix in double precision. Columns within a row are sorted ascending.
struct CsrMatrix {
  Index rows = 0;
  Index cols = 0;
  std::vector<Index> rowPtr{0};  ///< rows + 1 entries, rowPtr[0] = 0, non-decreasing
  std::vector<Index> colIdx;     ///< nonZeros() column indices
  std::vector<double> values;    ///< nonZeros() values

  std::size_t nonZeros() const noexcept { return values.size(); }

  /// Checks structure (sizes, monotone row pointers, column range, sorted unique columns) and values.
  /// @throws InvalidArgument naming the row and column of the first offending element, e.g. a NaN or Inf.
  void validate() const;

  /// y = A·x in double precision (the reference SpMV). @throws InvalidArgument on a size mismatch.
  Eigen::VectorXd multiply(const Eigen::VectorXd& x) const;

  /// The diagonal (zero where a row stores no diagonal entry).
  Eigen::VectorXd diagonal() const;

  /// Whether |A_ij − A_ji| ≤ tol·max|A| for every stored entry (missing entries count as 0).
  bool isSymmetric(double tol = 1e-12) const;

  /// The same matrix as an Eigen row-major sparse matrix (for Eigen's solvers in tests and benchmarks).
  Eigen::SparseMatrix<double, Eigen::RowMajor, Index> toEigen() const;

  /// Builds a CSR matrix from an Eigen sparse matrix (any storage order).
  static CsrMatrix fromEigen(const Eigen::SparseMatrix<double, Eigen::RowMajor, Index>& m);
};

}  // namespace duplexfit
