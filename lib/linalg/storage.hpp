// Internal storage behind DeviceVector and DeviceCsr: host arrays on the reference device, OpenCL buffers
// otherwise, plus the small helpers every linalg operation uses.
#pragma once

#include <CL/opencl.hpp>

#include <algorithm>
#include <string>
#include <vector>

#include "device/cl_check.hpp"
#include "device/device_impl.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/linalg.hpp"

namespace duplexfit::detail {

struct VectorStorage {
  Device device;
  std::size_t n = 0;
  Precision precision = Precision::Float;
  std::vector<float> f;   ///< reference device, float
  std::vector<double> d;  ///< reference device, double
  cl::Buffer buffer;      ///< OpenCL device (null when n == 0)

  template <typename T>
  std::vector<T>& host();
  template <typename T>
  const std::vector<T>& host() const {
    return const_cast<VectorStorage*>(this)->host<T>();
  }
};
template <>
inline std::vector<float>& VectorStorage::host<float>() {
  return f;
}
template <>
inline std::vector<double>& VectorStorage::host<double>() {
  return d;
}

struct CsrStorage {
  Device device;
  std::size_t rows = 0, cols = 0, nnz = 0;
  Precision precision = Precision::Float;
  Eigen::VectorXd diagonal;
  std::vector<Index> rowPtr, colIdx;  ///< reference device
  std::vector<float> valF;
  std::vector<double> valD;
  cl::Buffer rowPtrBuf, colBuf, valBuf;  ///< OpenCL device

  template <typename T>
  const std::vector<T>& values() const;
};
template <>
inline const std::vector<float>& CsrStorage::values<float>() const {
  return valF;
}
template <>
inline const std::vector<double>& CsrStorage::values<double>() const {
  return valD;
}

inline std::size_t sizeOf(Precision p) { return p == Precision::Double ? sizeof(double) : sizeof(float); }

/// A read-write buffer of `bytes` after checking the device's allocation limit; null for 0 bytes.
cl::Buffer createBuffer(const Device& device, std::size_t bytes, const std::string& what);

/// A buffer holding `count` elements copied from `data` (blocking write; a one-element buffer for none).
template <typename T>
cl::Buffer uploadArray(const Device& device, const T* data, std::size_t count, const std::string& what) {
  cl::Buffer b = createBuffer(device, std::max<std::size_t>(count, 1) * sizeof(T), what);
  if (count > 0) {
    DUPLEXFIT_CL_CHECK(device.impl()->queue().enqueueWriteBuffer(b, CL_TRUE, 0, count * sizeof(T), data));
  }
  return b;
}

/// Reads the first `count` elements of `buffer` into `data` (blocking).
template <typename T>
void readArray(const Device& device, const cl::Buffer& buffer, T* data, std::size_t count) {
  if (count > 0) {
    DUPLEXFIT_CL_CHECK(device.impl()->queue().enqueueReadBuffer(buffer, CL_TRUE, 0, count * sizeof(T), data));
  }
}

/// Sets a REAL kernel argument as float or double according to the precision.
void setRealArg(cl::Kernel& kernel, cl_uint index, double value, Precision precision, const char* name);

/// Throws InvalidArgument unless all operands share one device and precision (and sizes where given).
void checkCompatible(const char* op, const DeviceVector& a, const DeviceVector& b);

/// Sums n partial results (REAL) from a device buffer on the host in double.
std::vector<double> readPartials(DeviceImpl& impl, const cl::Buffer& buffer, std::size_t n, Precision p);

/// Calls f.template operator()<T>() with T = float or double.
template <typename F>
decltype(auto) dispatch(Precision p, F&& f) {
  if (p == Precision::Double) return f(double{});
  return f(float{});
}

}  // namespace duplexfit::detail
