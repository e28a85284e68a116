// Sparse matrix-vector products: row-per-work-item and row-per-group CSR kernels, and the fused
// SpMV + dot product of CG, with reference twins.
#include "device/cl_check.hpp"
#include "duplexfit/error.hpp"
#include "linalg/ops.hpp"
#include "linalg/storage.hpp"

namespace duplexfit {

using detail::dispatch;

namespace {

void checkSpmv(const DeviceCsr& a, const DeviceVector& x, const DeviceVector& y) {
  if (x.size() != a.cols() || y.size() != a.rows()) {
    throw InvalidArgument("spmv: matrix is " + std::to_string(a.rows()) + "x" + std::to_string(a.cols()) +
                          " but x has " + std::to_string(x.size()) + " and y " + std::to_string(y.size()) +
                          " entries");
  }
  if (a.rows() == 0 || a.cols() == 0) return;
  if (x.precision() != a.precision() || y.precision() != a.precision()) {
    throw InvalidArgument("spmv: matrix and vectors differ in precision");
  }
  if (x.device().impl() != a.device().impl() || y.device().impl() != a.device().impl()) {
    throw InvalidArgument("spmv: matrix and vectors live on different devices");
  }
}

template <typename T>
double referenceSpmv(const detail::CsrStorage& s, const T* x, T* y, bool withDot) {
  const auto rows = static_cast<std::ptrdiff_t>(s.rows);
  const Index* rp = s.rowPtr.data();
  const Index* ci = s.colIdx.data();
  const T* v = s.values<T>().data();
  double d = 0.0;
#pragma omp parallel for schedule(static) reduction(+ : d)
  for (std::ptrdiff_t i = 0; i < rows; ++i) {
    T acc = 0;
    for (Index k = rp[i]; k < rp[i + 1]; ++k) acc += v[k] * x[ci[k]];
    y[i] = acc;
    if (withDot) d += static_cast<double>(x[i] * acc);
  }
  return d;
}

}  // namespace

namespace steps {

using namespace detail;  // the launch helpers

SpmvKernel resolveSpmvKernel(const Device& device, SpmvKernel kernel) {
  if (kernel != SpmvKernel::Auto || device.isReference()) return kernel;
  return device.impl()->params().chunkReductions ? SpmvKernel::RowPerItem : SpmvKernel::RowPerGroup;
}

namespace {

void launchSpmv(const DeviceCsr& a, const DeviceVector& x, DeviceVector& y, SpmvKernel kernel) {
  auto& impl = *a.device().impl();
  const auto& s = a.storage();
  const auto& p = impl.params();
  const bool group = resolveSpmvKernel(a.device(), kernel) == SpmvKernel::RowPerGroup;
  const char* name = group ? "spmv_csr_group" : "spmv_csr_row";
  cl::Kernel& k = impl.kernel("spmv", a.precision(), name);
  setArgs(k, name, static_cast<cl_uint>(s.rows), s.rowPtrBuf, s.colBuf, s.valBuf, x.storage().buffer,
          y.storage().buffer);
  if (group) {
    const std::size_t rowsPerGroup = p.workGroup / p.lanes;
    impl.launch(k, (s.rows + rowsPerGroup - 1) / rowsPerGroup * p.workGroup, p.workGroup, name);
  } else {
    impl.launch(k, s.rows, p.workGroup, name);
  }
}

}  // namespace

double spmvDot(const DeviceCsr& a, const DeviceVector& x, DeviceVector& y, SpmvKernel kernel) {
  checkSpmv(a, x, y);
  if (a.rows() != a.cols()) throw InvalidArgument("spmvDot needs a square matrix");
  if (a.rows() == 0) return 0.0;
  return dispatch(a.precision(), [&](auto zero) -> double {
    using T = decltype(zero);
    if (a.device().isReference()) {
      return referenceSpmv<T>(a.storage(), x.storage().host<T>().data(), y.storage().host<T>().data(), true);
    }
    auto& impl = *a.device().impl();
    const auto& p = impl.params();
    if (resolveSpmvKernel(a.device(), kernel) == SpmvKernel::RowPerItem && p.chunkReductions) {
      const auto& s = a.storage();
      const char* name = "spmv_csr_row_dot_chunk";
      cl::Kernel& k = impl.kernel("spmv", a.precision(), name);
      setArgs(k, name, static_cast<cl_uint>(s.rows), s.rowPtrBuf, s.colBuf, s.valBuf, x.storage().buffer,
              y.storage().buffer);
      const std::size_t parts = (s.rows + p.chunk - 1) / p.chunk;
      cl::Buffer& scratch = impl.scratch(parts * sizeof(T));
      setArg(k, 6, scratch, name);
      impl.launch(k, parts, p.workGroup, name);
      double d = 0.0;
      for (double v : readPartials(impl, scratch, parts, a.precision())) d += v;
      return d;
    }
    launchSpmv(a, x, y, kernel);
    return dot(x, y);
  });
}

}  // namespace steps

void spmv(const DeviceCsr& a, const DeviceVector& x, DeviceVector& y, SpmvKernel kernel) {
  checkSpmv(a, x, y);
  if (a.rows() == 0) return;
  if (a.cols() == 0 || a.nonZeros() == 0) {
    y.fill(0.0);
    return;
  }
  dispatch(a.precision(), [&](auto zero) {
    using T = decltype(zero);
    if (a.device().isReference()) {
      referenceSpmv<T>(a.storage(), x.storage().host<T>().data(), y.storage().host<T>().data(), false);
      return;
    }
    steps::launchSpmv(a, x, y, kernel);
  });
}

}  // namespace duplexfit
