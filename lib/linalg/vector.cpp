// DeviceVector and DeviceCsr: allocation, upload and download on the reference or an OpenCL device.
#include <sstream>

#include "device/cl_check.hpp"
#include "duplexfit/error.hpp"
#include "linalg/storage.hpp"

namespace duplexfit {

namespace detail {

cl::Buffer createBuffer(const Device& device, std::size_t bytes, const std::string& what) {
  device.checkAllocation(bytes, what);
  if (bytes == 0) return cl::Buffer();
  cl_int status = CL_SUCCESS;
  cl::Buffer buffer(device.impl()->context(), CL_MEM_READ_WRITE, bytes, nullptr, &status);
  if (status != CL_SUCCESS) throwClError(status, "clCreateBuffer(" + what + ")");
  return buffer;
}

void setRealArg(cl::Kernel& kernel, cl_uint index, double value, Precision precision, const char* name) {
  if (precision == Precision::Double) {
    setArg(kernel, index, value, name);
  } else {
    setArg(kernel, index, static_cast<float>(value), name);
  }
}

void checkCompatible(const char* op, const DeviceVector& a, const DeviceVector& b) {
  if (a.size() != b.size()) {
    throw InvalidArgument(std::string(op) + ": vector sizes differ (" + std::to_string(a.size()) + " and " +
                          std::to_string(b.size()) + ")");
  }
  if (a.size() == 0) return;
  if (a.precision() != b.precision()) throw InvalidArgument(std::string(op) + ": vector precisions differ");
  if (a.device().impl() != b.device().impl()) {
    throw InvalidArgument(std::string(op) + ": vectors live on different devices");
  }
}

std::vector<double> readPartials(DeviceImpl& impl, const cl::Buffer& buffer, std::size_t n, Precision p) {
  std::vector<double> out(n);
  if (n == 0) return out;
  dispatch(p, [&](auto zero) {
    using T = decltype(zero);
    std::vector<T> tmp(n);
    DUPLEXFIT_CL_CHECK(impl.queue().enqueueReadBuffer(buffer, CL_TRUE, 0, n * sizeof(T), tmp.data()));
    for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<double>(tmp[i]);
  });
  return out;
}

}  // namespace detail

using detail::dispatch;

DeviceVector::DeviceVector() = default;
DeviceVector::DeviceVector(DeviceVector&&) noexcept = default;
DeviceVector& DeviceVector::operator=(DeviceVector&&) noexcept = default;
DeviceVector::~DeviceVector() = default;

DeviceVector::DeviceVector(const Device& device, std::size_t n, Precision precision)
    : storage_(std::make_unique<detail::VectorStorage>(detail::VectorStorage{device, n, precision, {}, {}, {}})) {
  device.requirePrecision(precision);
  if (device.isReference()) {
    device.checkAllocation(n * detail::sizeOf(precision), "a vector of " + std::to_string(n) + " values");
    if (precision == Precision::Double) {
      storage_->d.assign(n, 0.0);
    } else {
      storage_->f.assign(n, 0.0f);
    }
  } else {
    storage_->buffer = detail::createBuffer(device, n * detail::sizeOf(precision),
                                            "a vector of " + std::to_string(n) + " values");
    fill(0.0);
  }
}

DeviceVector DeviceVector::upload(const Device& device, const Eigen::VectorXd& x, Precision precision) {
  DeviceVector v(device, static_cast<std::size_t>(x.size()), precision);
  v.assign(x);
  return v;
}

void DeviceVector::assign(const Eigen::VectorXd& x) {
  if (static_cast<std::size_t>(x.size()) != size()) {
    throw InvalidArgument("DeviceVector::assign: " + std::to_string(x.size()) + " values for a vector of " +
                          std::to_string(size()));
  }
  if (size() == 0) return;
  auto& s = *storage_;
  dispatch(s.precision, [&](auto zero) {
    using T = decltype(zero);
    if (s.device.isReference()) {
      auto& h = s.host<T>();
      for (std::size_t i = 0; i < s.n; ++i) h[i] = static_cast<T>(x[static_cast<Eigen::Index>(i)]);
    } else {
      std::vector<T> tmp(s.n);
      for (std::size_t i = 0; i < s.n; ++i) tmp[i] = static_cast<T>(x[static_cast<Eigen::Index>(i)]);
      DUPLEXFIT_CL_CHECK(
          s.device.impl()->queue().enqueueWriteBuffer(s.buffer, CL_TRUE, 0, s.n * sizeof(T), tmp.data()));
    }
  });
}

Eigen::VectorXd DeviceVector::download() const {
  Eigen::VectorXd out(static_cast<Eigen::Index>(size()));
  if (size() == 0) return out;
  const auto& s = *storage_;
  dispatch(s.precision, [&](auto zero) {
    using T = decltype(zero);
    if (s.device.isReference()) {
      const auto& h = s.host<T>();
      for (std::size_t i = 0; i < s.n; ++i) out[static_cast<Eigen::Index>(i)] = static_cast<double>(h[i]);
    } else {
      std::vector<T> tmp(s.n);
      DUPLEXFIT_CL_CHECK(
          s.device.impl()->queue().enqueueReadBuffer(s.buffer, CL_TRUE, 0, s.n * sizeof(T), tmp.data()));
      for (std::size_t i = 0; i < s.n; ++i) out[static_cast<Eigen::Index>(i)] = static_cast<double>(tmp[i]);
    }
  });
  return out;
}

void DeviceVector::fill(double value) {
  if (size() == 0) return;
  auto& s = *storage_;
  dispatch(s.precision, [&](auto zero) {
    using T = decltype(zero);
    if (s.device.isReference()) {
      std::fill(s.host<T>().begin(), s.host<T>().end(), static_cast<T>(value));
    } else {
      DUPLEXFIT_CL_CHECK(s.device.impl()->queue().enqueueFillBuffer(s.buffer, static_cast<T>(value), 0,
                                                                    s.n * sizeof(T)));
    }
  });
}

DeviceVector DeviceVector::clone() const {
  if (!storage_) return DeviceVector();
  const auto& s = *storage_;
  DeviceVector out(s.device, s.n, s.precision);
  if (s.n == 0) return out;
  if (s.device.isReference()) {
    out.storage_->f = s.f;
    out.storage_->d = s.d;
  } else {
    DUPLEXFIT_CL_CHECK(s.device.impl()->queue().enqueueCopyBuffer(s.buffer, out.storage_->buffer, 0, 0,
                                                                  s.n * detail::sizeOf(s.precision)));
  }
  return out;
}

std::size_t DeviceVector::size() const noexcept { return storage_ ? storage_->n : 0; }
Precision DeviceVector::precision() const noexcept {
  return storage_ ? storage_->precision : Precision::Float;
}
const Device& DeviceVector::device() const {
  if (!storage_) throw InvalidArgument("DeviceVector is empty (default-constructed or moved from)");
  return storage_->device;
}

// ---- DeviceCsr

DeviceCsr::DeviceCsr() = default;
DeviceCsr::DeviceCsr(DeviceCsr&&) noexcept = default;
DeviceCsr& DeviceCsr::operator=(DeviceCsr&&) noexcept = default;
DeviceCsr::~DeviceCsr() = default;

DeviceCsr detail::adoptCsr(std::unique_ptr<CsrStorage> storage) {
  DeviceCsr m;
  m.storage_ = std::move(storage);
  return m;
}

DeviceCsr DeviceCsr::upload(const Device& device, const CsrMatrix& a, Precision precision) {
  return upload(device, a, precision, DeviceCsr{});
}

DeviceCsr DeviceCsr::upload(const Device& device, const CsrMatrix& a, Precision precision, DeviceCsr&& recycled) {
  std::unique_ptr<detail::CsrStorage> old = std::move(recycled.storage_);
  a.validate();
  device.requirePrecision(precision);
  DeviceCsr m;
  m.storage_ = std::make_unique<detail::CsrStorage>(detail::CsrStorage{device, 0, 0, 0, precision, {}, {}, {}, {}, {}, {}, {}, {}});
  auto& s = *m.storage_;
  s.rows = static_cast<std::size_t>(a.rows);
  s.cols = static_cast<std::size_t>(a.cols);
  s.nnz = a.nonZeros();
  s.diagonal = a.diagonal();
  const std::string what = "a " + std::to_string(s.rows) + "x" + std::to_string(s.cols) + " matrix with " +
                           std::to_string(s.nnz) + " non-zeros";
  const std::size_t valueBytes = s.nnz * detail::sizeOf(precision);
  device.checkAllocation(valueBytes, "the values of " + what);
  device.checkAllocation(s.nnz * sizeof(Index), "the column indices of " + what);
  dispatch(precision, [&](auto zero) {
    using T = decltype(zero);
    if (device.isReference()) {
      s.rowPtr = a.rowPtr;
      s.colIdx = a.colIdx;
      if constexpr (std::is_same_v<T, double>) {
        s.valD = a.values;
      } else {
        s.valF.assign(a.values.begin(), a.values.end());
      }
      return;
    }
    auto& queue = device.impl()->queue();
    // A buffer of the recycled matrix serves when it is on this device and holds `bytes`; the others are
    // released first, so that old and new buffers are not held at once.
    const bool sameDevice = old && old->device.impl() == device.impl() && !old->device.isReference();
    const auto reuse = [&](cl::Buffer& from, std::size_t bytes) {
      cl::Buffer b;
      if (sameDevice && bytes > 0 && from() != nullptr && from.getInfo<CL_MEM_SIZE>() >= bytes) b = from;
      from = cl::Buffer();
      return b;
    };
    cl::Buffer rowPtrOld, colOld, valOld;
    if (old) {
      rowPtrOld = reuse(old->rowPtrBuf, (s.rows + 1) * sizeof(Index));
      colOld = reuse(old->colBuf, s.nnz * sizeof(Index));
      valOld = reuse(old->valBuf, valueBytes);
      old.reset();
    }
    s.rowPtrBuf = rowPtrOld() != nullptr ? rowPtrOld : detail::createBuffer(device, (s.rows + 1) * sizeof(Index), "the row pointers of " + what);
    s.colBuf = colOld() != nullptr ? colOld : detail::createBuffer(device, s.nnz * sizeof(Index), "the column indices of " + what);
    s.valBuf = valOld() != nullptr ? valOld : detail::createBuffer(device, valueBytes, "the values of " + what);
    if (s.rows > 0) {
      DUPLEXFIT_CL_CHECK(queue.enqueueWriteBuffer(s.rowPtrBuf, CL_TRUE, 0, (s.rows + 1) * sizeof(Index),
                                                  a.rowPtr.data()));
    }
    if (s.nnz > 0) {
      // The columns and values are written through mapped buffers, filled by all threads: on a CPU device
      // the map is the buffer's own memory, whose fresh pages are then faulted in in parallel, and the
      // float values are rounded in place (a large level's host copy in float cost 0.4 s).
      const auto count = static_cast<std::ptrdiff_t>(s.nnz);
      const auto fill = [&](const cl::Buffer& buffer, std::size_t bytes, const auto& write) {
        cl_int status = CL_SUCCESS;
        void* mapped =
            queue.enqueueMapBuffer(buffer, CL_TRUE, CL_MAP_WRITE_INVALIDATE_REGION, 0, bytes, nullptr, nullptr, &status);
        DUPLEXFIT_CL_CHECK(status);
        write(mapped);
        cl::Event unmapped;
        DUPLEXFIT_CL_CHECK(queue.enqueueUnmapMemObject(buffer, mapped, nullptr, &unmapped));
        DUPLEXFIT_CL_CHECK(unmapped.wait());
      };
      fill(s.colBuf, s.nnz * sizeof(Index), [&](void* mapped) {
        auto* out = static_cast<Index*>(mapped);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t k = 0; k < count; ++k) out[k] = a.colIdx[static_cast<std::size_t>(k)];
      });
      fill(s.valBuf, valueBytes, [&](void* mapped) {
        auto* out = static_cast<T*>(mapped);
#pragma omp parallel for schedule(static)
        for (std::ptrdiff_t k = 0; k < count; ++k) out[k] = static_cast<T>(a.values[static_cast<std::size_t>(k)]);
      });
    }
  });
  return m;
}

std::size_t DeviceCsr::rows() const noexcept { return storage_ ? storage_->rows : 0; }
std::size_t DeviceCsr::cols() const noexcept { return storage_ ? storage_->cols : 0; }
std::size_t DeviceCsr::nonZeros() const noexcept { return storage_ ? storage_->nnz : 0; }
Precision DeviceCsr::precision() const noexcept { return storage_ ? storage_->precision : Precision::Float; }
const Device& DeviceCsr::device() const {
  if (!storage_) throw InvalidArgument("DeviceCsr is empty (default-constructed or moved from)");
  return storage_->device;
}
const Eigen::VectorXd& DeviceCsr::diagonal() const {
  if (!storage_) throw InvalidArgument("DeviceCsr is empty (default-constructed or moved from)");
  return storage_->diagonal;
}
double DeviceCsr::spmvBytes() const noexcept {
  if (!storage_) return 0.0;
  const double real = static_cast<double>(detail::sizeOf(storage_->precision));
  const auto& s = *storage_;
  return static_cast<double>(s.nnz) * (real + sizeof(Index)) + static_cast<double>(s.rows + 1) * sizeof(Index) +
         static_cast<double>(s.cols) * real + static_cast<double>(s.rows) * real;
}

}  // namespace duplexfit
