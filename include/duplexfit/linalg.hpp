// Vectors and CSR matrices that live on a Device, the BLAS-1 and SpMV operations on them, and the
// preconditioned conjugate gradient solver used by every hierarchy level (docs: docs/method.md §5).
// Every operation runs either as OpenCL kernels or, on Device::reference(), as plain C++ loops
// with the same arithmetic precision.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include <Eigen/Core>

#include "duplexfit/device.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

class DeviceCsr;
namespace detail {
struct VectorStorage;
struct CsrStorage;
/// Internal: a DeviceCsr over storage already filled on the device (the device assembly).
DeviceCsr adoptCsr(std::unique_ptr<CsrStorage> storage);
}  // namespace detail

/// A vector of n values of one precision on one device. Move-only; clone() copies explicitly.
class DeviceVector {
 public:
  DeviceVector();
  /// n zeros. @throws DeviceError if the precision is unavailable or n values exceed the max allocation.
  DeviceVector(const Device& device, std::size_t n, Precision precision);
  /// Uploads x, rounded to the precision.
  static DeviceVector upload(const Device& device, const Eigen::VectorXd& x, Precision precision);
  DeviceVector(DeviceVector&&) noexcept;
  DeviceVector& operator=(DeviceVector&&) noexcept;
  ~DeviceVector();

  /// Replaces the contents (x.size() must equal size()).
  void assign(const Eigen::VectorXd& x);
  /// Copies the contents to the host, widened to double.
  Eigen::VectorXd download() const;
  /// Sets every element to value.
  void fill(double value);
  /// A deep copy on the same device.
  DeviceVector clone() const;

  std::size_t size() const noexcept;
  Precision precision() const noexcept;
  const Device& device() const;

  /// Internal storage (for kernel launches).
  detail::VectorStorage& storage() const { return *storage_; }

 private:
  std::unique_ptr<detail::VectorStorage> storage_;
};

/// A CSR matrix uploaded to a device in one precision (values rounded; indices as 32-bit integers).
class DeviceCsr {
 public:
  DeviceCsr();
  /// Validates A (CsrMatrix::validate), then uploads it.
  /// @throws InvalidArgument for malformed or non-finite matrices, DeviceError when a buffer exceeds the
  ///         device's max allocation or the precision is unavailable.
  static DeviceCsr upload(const Device& device, const CsrMatrix& a, Precision precision);
  /// As upload, into the device buffers of `recycled` where they are on the same device and large enough
  /// (a fresh buffer costs its pages again: a fit's finest level reuses the level before's); `recycled` is
  /// left empty, and buffers of it that are not reused are released before any new one is created.
  static DeviceCsr upload(const Device& device, const CsrMatrix& a, Precision precision, DeviceCsr&& recycled);
  DeviceCsr(DeviceCsr&&) noexcept;
  DeviceCsr& operator=(DeviceCsr&&) noexcept;
  ~DeviceCsr();

  std::size_t rows() const noexcept;
  std::size_t cols() const noexcept;
  std::size_t nonZeros() const noexcept;
  Precision precision() const noexcept;
  const Device& device() const;
  /// The diagonal, as stored on the host at upload time (double).
  const Eigen::VectorXd& diagonal() const;
  /// Bytes one SpMV must move at least (matrix, row pointers, x once, y): for GB/s figures.
  double spmvBytes() const noexcept;

  detail::CsrStorage& storage() const { return *storage_; }

 private:
  friend DeviceCsr detail::adoptCsr(std::unique_ptr<detail::CsrStorage> storage);
  std::unique_ptr<detail::CsrStorage> storage_;
};

/// How an SpMV maps rows to work-items. Auto picks RowPerItem on CPU devices (fastest on PoCL, see
/// docs/benchmarks.md) and RowPerGroup on GPUs.
enum class SpmvKernel { Auto, RowPerItem, RowPerGroup };

/// y ← A·x. Sizes must match and all operands live on the same device in the same precision.
void spmv(const DeviceCsr& a, const DeviceVector& x, DeviceVector& y, SpmvKernel kernel = SpmvKernel::Auto);
/// y ← alpha·x + y
void axpy(double alpha, const DeviceVector& x, DeviceVector& y);
/// y ← x + beta·y
void xpay(const DeviceVector& x, double beta, DeviceVector& y);
/// x·y, accumulated per work-item in the vector precision and summed on the host in double.
double dot(const DeviceVector& x, const DeviceVector& y);
/// ‖x‖₂
double norm2(const DeviceVector& x);

/// z ← M⁻¹ r for a symmetric positive definite M. Derive to plug a stronger preconditioner into solveCg.
class Preconditioner {
 public:
  virtual ~Preconditioner() = default;
  virtual void apply(const DeviceVector& r, DeviceVector& z) const = 0;
  /// z ← M⁻¹ r and returns r·z; override to fuse both into one pass.
  virtual double applyDot(const DeviceVector& r, DeviceVector& z) const;
  /// A diagonal preconditioner returns its inverse diagonal here; the solver then fuses it into its
  /// update kernels (one pass less per iteration). Others return nullptr.
  virtual const DeviceVector* inverseDiagonal() const { return nullptr; }
  virtual std::string name() const = 0;
};

/// Jacobi: M = diag(A). For Wendland systems the diagonal is the constant 1 + λ, so it only rescales.
class JacobiPreconditioner final : public Preconditioner {
 public:
  /// @throws InvalidArgument when a diagonal entry is zero, negative or not finite (A is not SPD).
  explicit JacobiPreconditioner(const DeviceCsr& a);
  void apply(const DeviceVector& r, DeviceVector& z) const override;
  const DeviceVector* inverseDiagonal() const override { return &invDiag_; }
  std::string name() const override { return "jacobi"; }

 private:
  DeviceVector invDiag_;
};

/// Block Jacobi: M = the block diagonal of A with blocks of `blockSize` consecutive rows, applied with
/// the blocks' exact (Cholesky) inverses. Strong where rows couple mostly to nearby rows, e.g. Wendland
/// systems in spatial order, where each point sits next to its close offset and off-surface companions.
class BlockJacobiPreconditioner final : public Preconditioner {
 public:
  /// @param a the host matrix that was uploaded (its diagonal blocks are inverted on the host)
  /// @throws InvalidArgument when blockSize < 1 or a is not square; DeviceError as DeviceVector.
  BlockJacobiPreconditioner(const Device& device, const CsrMatrix& a, Precision precision, int blockSize = 16);
  void apply(const DeviceVector& r, DeviceVector& z) const override;
  double applyDot(const DeviceVector& r, DeviceVector& z) const override;
  std::string name() const override { return describe(blockSize_); }
  /// The name of a block Jacobi preconditioner with blocks of blockSize rows ("block-jacobi-16").
  static std::string describe(int blockSize) { return "block-jacobi-" + std::to_string(blockSize); }
  int blockSize() const noexcept { return blockSize_; }

 private:
  int blockSize_;
  std::size_t n_;
  DeviceVector inverses_;  ///< per block a dense row-major blockSize² inverse
};

/// Factorised sparse approximate inverse (FSAI, Kolotilina and Yeremin 1993): M⁻¹ = Gᵀ G ≈ A⁻¹ with G
/// lower triangular, row i supported on the diagonal and its strong couplings j < i, |a_ij| ≥
/// threshold·√(a_ii a_jj) (the maxNeighbours strongest where there are more); each row solves
/// A[S,S] g = e_i on its pattern S and is scaled so that (G A Gᵀ)_ii = 1. Built on the host in double,
/// applied as two SpMVs (G, then Gᵀ). On Wendland systems it couples each centre to its nearest ones
/// whatever their place in the ordering, where block Jacobi only sees fixed blocks of rows: fandisk_50k's
/// finest level takes 12 iterations instead of 141 (docs/benchmarks.md).
class FsaiPreconditioner final : public Preconditioner {
 public:
  /// @param a the host matrix that was uploaded (symmetric positive definite, columns sorted per row)
  /// @throws InvalidArgument when threshold is outside [0, 1], maxNeighbours outside [0, 64], a is not
  ///         square or has a_ii ≤ 0; DeviceError as DeviceCsr.
  FsaiPreconditioner(const Device& device, const CsrMatrix& a, Precision precision, double threshold = 0.2,
                     int maxNeighbours = 32);
  /// The same for `a` as DeviceCsr::upload put it on the device as `uploaded` (same device and precision):
  /// the upload validated `a` and kept its diagonal, so neither is done again (a quarter of the set-up on
  /// a fit's finest levels). @throws InvalidArgument also when the two differ in rows or non-zeros.
  FsaiPreconditioner(const DeviceCsr& uploaded, const CsrMatrix& a, double threshold = 0.2, int maxNeighbours = 32);
  void apply(const DeviceVector& r, DeviceVector& z) const override;
  std::string name() const override { return describe(threshold_, maxNeighbours_); }
  /// The name of an FSAI preconditioner with these parameters ("fsai (threshold 0.2, at most 32 couplings a row)").
  static std::string describe(double threshold, int maxNeighbours);
  /// Entries of G a row, on average (the diagonal included).
  double entriesPerRow() const noexcept { return n_ > 0 ? static_cast<double>(g_.nonZeros()) / static_cast<double>(n_) : 0.0; }
  /// Rows whose pattern block was not numerically SPD and that fell back to 1/√a_ii.
  std::size_t fallbackRows() const noexcept { return fallbacks_; }

 private:
  double threshold_;
  int maxNeighbours_;
  std::size_t n_;
  std::size_t fallbacks_ = 0;
  DeviceCsr g_, gt_;
  mutable DeviceVector tmp_;  ///< G r

  /// The set-up of both constructors, on a validated `a` with its diagonal.
  void build(const Device& device, const CsrMatrix& a, const Eigen::VectorXd& diagonal, Precision precision);
};

/// Why a CG solve stopped.
enum class StopReason {
  Converged,       ///< the recursive residual met ‖r‖ ≤ tol·‖b‖ (or max|r_i| ≤ the absolute tolerance) and
                   ///< so does the true residual b − Ax, recomputed (float rounding makes the two drift
                   ///< apart; the solver restarts from the true residual up to 3 times before reporting
                   ///< Stagnated). SolveStats::relativeResidual is always the true one.
  ZeroRhs,         ///< b = 0: x = 0 is exact
  IterationLimit,  ///< maxIterations reached
  Breakdown,       ///< pᵀAp ≤ 0 or rᵀz ≤ 0: the matrix or preconditioner is not positive definite
  NonFinite,       ///< a NaN or Inf appeared (overflow, or non-finite input vectors)
  Stagnated,       ///< the recursive residual met the tolerance but the true one stayed above it
                   ///< after restarts (the precision cannot reach the tolerance)
  Cancelled        ///< the Interrupter interrupted
};
const char* stopReasonName(StopReason reason) noexcept;

struct SolverOptions {
  int maxIterations = 20000;         ///< iteration cap (fine levels can need thousands, docs/method.md §5)
  double relativeTolerance = 0.0;    ///< stop at ‖r‖ ≤ tol·‖b‖; 0: 1e-6 in double, 1e-5 in float
  /// Also stop when max_i |r_i| ≤ absoluteTolerance (0: off). The level solves of a fit set it: there
  /// r_i is exactly the remaining fit error at centre i.
  double absoluteTolerance = 0.0;
  bool useFusedKernels = true;       ///< fused CG updates (fewer passes over memory) where possible
  SpmvKernel spmvKernel = SpmvKernel::Auto;
  /// Every progressInterval iterations solveCg sends the interrupter a FitEvent{Solve, iteration,
  /// relative residual} and then polls wasInterrupted(); 0: never.
  int progressInterval = 50;
};

/// Outcome of a solve; non-convergence is reported here, never thrown.
struct SolveStats {
  bool converged = false;
  StopReason reason = StopReason::IterationLimit;
  int iterations = 0;
  double relativeResidual = 0.0;     ///< ‖b − Ax‖/‖b‖ recomputed from x at the end (true residual)
  double recurrenceResidual = 0.0;   ///< the solver's own ‖r‖/‖b‖ when it stopped
  double maxResidual = 0.0;          ///< max_i |b − Ax|_i of the returned x (true residual)
  double tolerance = 0.0;            ///< the tolerance actually used
  double absoluteTolerance = 0.0;    ///< the absolute tolerance used (0: none)
  double seconds = 0.0;
};

/// Solves A x = b by preconditioned conjugate gradients; x holds the start vector on entry.
/// @param preconditioner nullptr: Jacobi built from A.
/// @param interrupter may be null; when it interrupts, the solve stops with StopReason::Cancelled.
/// @throws InvalidArgument on mismatched sizes, devices or precisions; DeviceError on OpenCL failures.
SolveStats solveCg(const DeviceCsr& a, const DeviceVector& b, DeviceVector& x, const SolverOptions& options = {},
                   const Preconditioner* preconditioner = nullptr, Interrupter* interrupter = nullptr);

}  // namespace duplexfit
