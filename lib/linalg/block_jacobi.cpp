// Block Jacobi preconditioner: dense inverses of A's diagonal blocks (Cholesky on the host, identity
// padding for the last block), applied by the block_jacobi kernel or its reference twin.
#include <Eigen/Cholesky>

#include "duplexfit/error.hpp"
#include "linalg/ops.hpp"
#include "linalg/storage.hpp"

namespace duplexfit {

BlockJacobiPreconditioner::BlockJacobiPreconditioner(const Device& device, const CsrMatrix& a, Precision precision,
                                                     int blockSize)
    : blockSize_(blockSize), n_(static_cast<std::size_t>(a.rows)) {
  if (blockSize < 1 || blockSize > 256) throw InvalidArgument("block Jacobi: blockSize must be in [1, 256]");
  if (a.rows != a.cols) throw InvalidArgument("block Jacobi: the matrix is not square");
  const auto bs = static_cast<std::size_t>(blockSize);
  const std::size_t blocks = (n_ + bs - 1) / bs;
  Eigen::VectorXd packed = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(blocks * bs * bs));
#pragma omp parallel for schedule(dynamic, 64)
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(blocks); ++b) {
    const std::size_t base = static_cast<std::size_t>(b) * bs;
    const std::size_t m = std::min(bs, n_ - base);
    Eigen::MatrixXd block = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(m));
    for (std::size_t i = 0; i < m; ++i) {
      const std::size_t row = base + i;
      for (Index k = a.rowPtr[row]; k < a.rowPtr[row + 1]; ++k) {
        const auto c = static_cast<std::size_t>(a.colIdx[static_cast<std::size_t>(k)]);
        if (c >= base && c < base + m) {
          block(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c - base)) = a.values[static_cast<std::size_t>(k)];
        }
      }
    }
    Eigen::MatrixXd inv;
    const Eigen::LLT<Eigen::MatrixXd> llt(block);
    if (llt.info() == Eigen::Success) {
      inv = llt.solve(Eigen::MatrixXd::Identity(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(m)));
      // Exactly symmetric (the solve leaves rounding differences between (i, j) and (j, i)): PCG assumes
      // a symmetric M, and the CPU kernel reads row j of a block as its column j (kernels/precond.cl).
      inv = (0.5 * (inv + inv.transpose())).eval();
    } else {  // not numerically SPD: fall back to the diagonal (Jacobi) for this block
      inv = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(m), static_cast<Eigen::Index>(m));
      for (Eigen::Index i = 0; i < inv.rows(); ++i) inv(i, i) = block(i, i) > 0.0 ? 1.0 / block(i, i) : 1.0;
    }
    for (std::size_t i = 0; i < m; ++i) {
      for (std::size_t j = 0; j < m; ++j) {
        packed[static_cast<Eigen::Index>((base + i) * bs + j)] = inv(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
      }
    }
  }
  inverses_ = DeviceVector::upload(device, packed, precision);
}

void BlockJacobiPreconditioner::apply(const DeviceVector& r, DeviceVector& z) const {
  detail::checkCompatible("block Jacobi", r, z);
  if (r.size() != n_) throw InvalidArgument("block Jacobi: vector size does not match the matrix");
  if (n_ == 0) return;
  const auto bs = static_cast<std::size_t>(blockSize_);
  detail::dispatch(r.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (r.device().isReference()) {
      const T* inv = inverses_.storage().host<T>().data();
      const T* rs = r.storage().host<T>().data();
      T* zs = z.storage().host<T>().data();
#pragma omp parallel for schedule(static)
      for (std::ptrdiff_t i = 0; i < static_cast<std::ptrdiff_t>(n_); ++i) {
        const std::size_t base = static_cast<std::size_t>(i) / bs * bs;
        const std::size_t m = std::min(bs, n_ - base);
        const T* row = inv + static_cast<std::size_t>(i) * bs;
        T s = 0;
        for (std::size_t j = 0; j < m; ++j) s += row[j] * rs[base + j];
        zs[i] = s;
      }
      return;
    }
    auto& impl = *r.device().impl();
    cl::Kernel& k = impl.kernel("precond", r.precision(), "block_jacobi");
    detail::setArgs(k, "block_jacobi", static_cast<cl_uint>(n_), static_cast<cl_uint>(bs), inverses_.storage().buffer,
                    r.storage().buffer, z.storage().buffer);
    impl.launch(k, n_, impl.params().workGroup, "block_jacobi");
  });
}

}  // namespace duplexfit

namespace duplexfit {

double Preconditioner::applyDot(const DeviceVector& r, DeviceVector& z) const {
  apply(r, z);
  return dot(r, z);
}

double BlockJacobiPreconditioner::applyDot(const DeviceVector& r, DeviceVector& z) const {
  if (r.device().isReference() || n_ == 0) return Preconditioner::applyDot(r, z);
  detail::checkCompatible("block Jacobi", r, z);
  if (r.size() != n_) throw InvalidArgument("block Jacobi: vector size does not match the matrix");
  auto& impl = *r.device().impl();
  const char* name = impl.params().chunkReductions ? "block_jacobi_dot_chunk" : "block_jacobi_dot_group";
  cl::Kernel& k = impl.kernel("precond", r.precision(), name);
  detail::setArgs(k, name, static_cast<cl_uint>(n_), static_cast<cl_uint>(blockSize_), inverses_.storage().buffer,
                  r.storage().buffer, z.storage().buffer);
  return detail::reduceLaunch(r.device(), r.precision(), k, 5, n_, 1, name)[0];
}

}  // namespace duplexfit
