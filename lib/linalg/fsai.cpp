// Factorised sparse approximate inverse (FSAI) preconditioner: M⁻¹ = Gᵀ G ≈ A⁻¹ with G lower triangular,
// row i of G supported on i and the strong couplings j < i, |a_ij| ≥ τ √(a_ii a_jj) (at most the
// `maxNeighbours` strongest), after Kolotilina and Yeremin (1993): each row solves A[S,S] g = e_i on its
// pattern S and is scaled so that (G A Gᵀ)_ii = 1. Built on the host in double (each row independently),
// applied on the device as two SpMVs, G then Gᵀ (docs/method.md §5).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "parallel/omp_threads.hpp"

namespace duplexfit {

FsaiPreconditioner::FsaiPreconditioner(const Device& device, const CsrMatrix& a, Precision precision,
                                       double threshold, int maxNeighbours)
    : threshold_(threshold), maxNeighbours_(maxNeighbours), n_(static_cast<std::size_t>(a.rows)) {
  if (!(threshold >= 0.0 && threshold <= 1.0)) throw InvalidArgument("FSAI: threshold must be in [0, 1]");
  if (maxNeighbours < 0 || maxNeighbours > 64) throw InvalidArgument("FSAI: maxNeighbours must be in [0, 64]");
  if (a.rows != a.cols) throw InvalidArgument("FSAI: the matrix is not square");
  a.validate();  // sorted, in-range columns and finite values before any entry is looked up
  build(device, a, a.diagonal(), precision);
}

FsaiPreconditioner::FsaiPreconditioner(const DeviceCsr& uploaded, const CsrMatrix& a, double threshold,
                                       int maxNeighbours)
    : threshold_(threshold), maxNeighbours_(maxNeighbours), n_(static_cast<std::size_t>(a.rows)) {
  if (!(threshold >= 0.0 && threshold <= 1.0)) throw InvalidArgument("FSAI: threshold must be in [0, 1]");
  if (maxNeighbours < 0 || maxNeighbours > 64) throw InvalidArgument("FSAI: maxNeighbours must be in [0, 64]");
  if (a.rows != a.cols) throw InvalidArgument("FSAI: the matrix is not square");
  if (uploaded.rows() != n_ || uploaded.cols() != static_cast<std::size_t>(a.cols) ||
      uploaded.nonZeros() != a.values.size() || a.colIdx.size() != a.values.size() ||
      a.rowPtr.size() != n_ + 1 || static_cast<std::size_t>(uploaded.diagonal().size()) != n_) {
    throw InvalidArgument("FSAI: the host matrix (" + std::to_string(a.rows) + " rows, " + std::to_string(a.values.size()) +
                          " non-zeros) is not the uploaded one (" + std::to_string(uploaded.rows()) + " rows, " +
                          std::to_string(uploaded.nonZeros()) + " non-zeros)");
  }
  build(uploaded.device(), a, uploaded.diagonal(), uploaded.precision());
}

void FsaiPreconditioner::build(const Device& device, const CsrMatrix& a, const Eigen::VectorXd& diagonal,
                               Precision precision) {
  const double threshold = threshold_;
  const auto n = static_cast<std::ptrdiff_t>(n_);
  const auto k = static_cast<std::size_t>(maxNeighbours_);
  for (Index i = 0; i < a.rows; ++i) {
    const double d = diagonal[i];
    if (!(d > 0.0) || !std::isfinite(d)) {
      throw InvalidArgument("FSAI: diagonal entry " + std::to_string(i) + " is " + std::to_string(d) +
                            "; a symmetric positive definite matrix needs a_ii > 0");
    }
  }
  // The pattern is a threshold, not "the k largest": samplings with many equal distances would otherwise
  // choose among ties, and a rounding-level change of the input would change the choice.
  const auto strong = [&](Index i, Index j, double v) {
    return std::abs(v) >= threshold * std::sqrt(diagonal[i] * diagonal[j]);
  };
  // Row i's pattern: the diagonal and its strong couplings below it, the k strongest where there are more.
  CsrMatrix g;
  g.rows = a.rows;
  g.cols = a.cols;
  g.rowPtr.assign(n_ + 1, 0);
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < n; ++i) {
    std::size_t lower = 0;
    for (Index e = a.rowPtr[static_cast<std::size_t>(i)]; e < a.rowPtr[static_cast<std::size_t>(i) + 1]; ++e) {
      const Index j = a.colIdx[static_cast<std::size_t>(e)];
      if (j < i && strong(static_cast<Index>(i), j, a.values[static_cast<std::size_t>(e)])) ++lower;
    }
    g.rowPtr[static_cast<std::size_t>(i) + 1] = static_cast<Index>(std::min(lower, k) + 1);
  }
  for (std::size_t i = 0; i < n_; ++i) g.rowPtr[i + 1] += g.rowPtr[i];
  const auto nnz = static_cast<std::size_t>(g.rowPtr[n_]);
  g.colIdx.resize(nnz);
  g.values.resize(nnz);
  std::size_t fallbacks = 0;
#pragma omp parallel reduction(+ : fallbacks)
  {
    std::vector<std::pair<double, Index>> cand;
    std::vector<Index> s;
    std::vector<double> l, y;  // the pattern block's Cholesky factor (row-major, lower) and the solve
    std::vector<double> column;  // the factor's column being applied (its entries below the diagonal)
    // slot[j]: the place of column j in the current pattern, −1 for a column outside it (reset after each row).
    std::vector<std::int32_t> slot(n_, -1);
#pragma omp for schedule(dynamic, 4096)
    for (std::ptrdiff_t i = 0; i < n; ++i) {
      const auto row = static_cast<std::size_t>(i);
      cand.clear();
      const double diag = diagonal[i];
      for (Index e = a.rowPtr[row]; e < a.rowPtr[row + 1]; ++e) {
        const Index j = a.colIdx[static_cast<std::size_t>(e)];
        const double v = a.values[static_cast<std::size_t>(e)];
        if (j < i && strong(static_cast<Index>(i), j, v)) cand.emplace_back(-std::abs(v), j);
      }
      const std::size_t m = std::min(cand.size(), k);
      // beyond k: the strongest couplings first, ties by column (the same pattern on every thread); when
      // all are kept (nearly every row) the order does not matter, the pattern is sorted by column below.
      if (m < cand.size()) std::partial_sort(cand.begin(), cand.begin() + static_cast<std::ptrdiff_t>(m), cand.end());
      s.resize(m);
      for (std::size_t p = 0; p < m; ++p) s[p] = cand[p].second;
      std::sort(s.begin(), s.end());
      s.push_back(static_cast<Index>(i));
      const std::size_t size = s.size();
      // A[S,S]'s lower triangle into l: each pattern row's entries looked up in `slot` (one pass over the
      // row's columns below its own, instead of a binary search of the row for every pair; the rows of dense
      // levels hold 150-260 entries).
      l.assign(size * size, 0.0);
      for (std::size_t p = 0; p < size; ++p) slot[static_cast<std::size_t>(s[p])] = static_cast<std::int32_t>(p);
      for (std::size_t p = 0; p < size; ++p) {
        const auto r = static_cast<std::size_t>(s[p]);
        for (Index e = a.rowPtr[r]; e < a.rowPtr[r + 1]; ++e) {
          const Index j = a.colIdx[static_cast<std::size_t>(e)];
          if (j >= s[p]) break;  // sorted columns: the rest lie on or above the diagonal
          const std::int32_t q = slot[static_cast<std::size_t>(j)];
          if (q >= 0) l[p * size + static_cast<std::size_t>(q)] = a.values[static_cast<std::size_t>(e)];
        }
        l[p * size + p] = diagonal[s[p]];
      }
      for (std::size_t p = 0; p < size; ++p) slot[static_cast<std::size_t>(s[p])] = -1;
      // Cholesky of A[S,S] in place (lower triangle), then L Lᵀ g = e_last: L y = e_last gives
      // y = (0, …, 0, 1/l_last,last), so g = L⁻ᵀ y and the scaled row is g / √g_last.
      // Column by column (right-looking): column q is finished (its diagonal's root, the entries below
      // divided by it) and copied to `column`, then every later row p takes l_pq · column from its entries
      // q + 1 … p, a contiguous update the compiler vectorises. Each entry gets the same subtractions in the
      // same order (t = 0, 1, …) as in the row-by-row form, so the same bits; there each entry's sum was one
      // chain of dependent subtractions (wheel_29k's dense levels: 33-entry patterns, about 6k a row).
      bool spd = true;
      column.resize(size);
      for (std::size_t q = 0; q < size; ++q) {
        const double v = l[q * size + q];
        if (!(v > 0.0)) {
          spd = false;
          break;
        }
        const double root = std::sqrt(v);
        l[q * size + q] = root;
        for (std::size_t p = q + 1; p < size; ++p) column[p] = l[p * size + q] /= root;
        for (std::size_t p = q + 1; p < size; ++p) {
          const double f = column[p];
          double* lp = l.data() + p * size;
          for (std::size_t t = q + 1; t <= p; ++t) lp[t] -= f * column[t];
        }
      }
      const std::size_t out = static_cast<std::size_t>(g.rowPtr[row]);
      if (spd) {
        y.assign(size, 0.0);
        const std::size_t last = size - 1;
        y[last] = 1.0 / l[last * size + last];
        for (std::size_t p = size; p-- > 0;) {  // Lᵀ g = y, back substitution
          double v = y[p];
          for (std::size_t t = p + 1; t < size; ++t) v -= l[t * size + p] * y[t];
          y[p] = v / l[p * size + p];
        }
        // g_last = 1 / l_last,last², so g / √g_last = g · l_last,last
        const double scale = l[last * size + last];
        for (std::size_t p = 0; p < size; ++p) {
          g.colIdx[out + p] = s[p];
          g.values[out + p] = y[p] * scale;
        }
        spd = std::all_of(g.values.begin() + static_cast<std::ptrdiff_t>(out),
                          g.values.begin() + static_cast<std::ptrdiff_t>(out + size), [](double v) { return std::isfinite(v); });
      }
      if (!spd) {  // not numerically SPD: this row falls back to Jacobi's 1/√a_ii (checked > 0 above)
        ++fallbacks;
        for (std::size_t p = 0; p < size; ++p) {
          g.colIdx[out + p] = s[p];
          g.values[out + p] = p + 1 == size ? 1.0 / std::sqrt(diag) : 0.0;
        }
      }
    }
  }
  fallbacks_ = fallbacks;
  // Gᵀ in CSR: a counting sort by column, rows split between the threads (each counts its own rows'
  // columns; a column's entries go in row order, so each row of Gᵀ comes out sorted).
  CsrMatrix gt;
  gt.rows = a.rows;
  gt.cols = a.cols;
  gt.rowPtr.assign(n_ + 1, 0);
  gt.colIdx.resize(nnz);
  gt.values.resize(nnz);
  const int threads = std::max(1, detail::maxThreads());
  std::vector<std::vector<Index>> counts(static_cast<std::size_t>(threads));
#pragma omp parallel num_threads(threads)
  {
    // The rows split by the team's actual size (the runtime may give fewer threads than asked).
    const auto t = static_cast<std::size_t>(detail::threadId()), nt = static_cast<std::size_t>(detail::teamSize());
    const std::size_t r0 = n_ * t / nt, r1 = n_ * (t + 1) / nt;
    std::vector<Index>& c = counts[t];
    c.assign(n_, 0);
    for (auto e = static_cast<std::size_t>(g.rowPtr[r0]); e < static_cast<std::size_t>(g.rowPtr[r1]); ++e) {
      ++c[static_cast<std::size_t>(g.colIdx[e])];
    }
#pragma omp barrier
#pragma omp single
    {
      // per column: the threads' slots one after the other; c becomes each thread's next slot
      Index at = 0;
      for (std::size_t col = 0; col < n_; ++col) {
        gt.rowPtr[col] = at;
        for (std::size_t u = 0; u < nt; ++u) {
          Index& slot = counts[u][col];
          const Index here = slot;
          slot = at;
          at += here;
        }
      }
      gt.rowPtr[n_] = at;
    }
    for (std::size_t i = r0; i < r1; ++i) {
      for (Index e = g.rowPtr[i]; e < g.rowPtr[i + 1]; ++e) {
        const auto slot = static_cast<std::size_t>(c[static_cast<std::size_t>(g.colIdx[static_cast<std::size_t>(e)])]++);
        gt.colIdx[slot] = static_cast<Index>(i);
        gt.values[slot] = g.values[static_cast<std::size_t>(e)];
      }
    }
  }
  g_ = DeviceCsr::upload(device, g, precision);
  gt_ = DeviceCsr::upload(device, gt, precision);
  tmp_ = DeviceVector(device, n_, precision);
}

std::string FsaiPreconditioner::describe(double threshold, int maxNeighbours) {
  std::ostringstream s;
  s << "fsai (threshold " << threshold << ", at most " << maxNeighbours << " couplings a row)";
  return s.str();
}

void FsaiPreconditioner::apply(const DeviceVector& r, DeviceVector& z) const {
  if (r.size() != n_ || z.size() != n_) {
    throw InvalidArgument("FSAI: vectors of " + std::to_string(r.size()) + " and " + std::to_string(z.size()) +
                          " entries for a " + std::to_string(n_) + "-row preconditioner");
  }
  // One row a work-item on every device: G's rows hold about 5 entries, and a GPU's row-per-group kernel
  // would leave most of a row's lanes idle (short rows favour one row a thread: Bell and Garland, SC 2009;
  // not measured here, no GPU was lent this session). On CPU devices it is the kernel Auto picks anyway.
  spmv(g_, r, tmp_, SpmvKernel::RowPerItem);
  spmv(gt_, tmp_, z, SpmvKernel::RowPerItem);
}

}  // namespace duplexfit
