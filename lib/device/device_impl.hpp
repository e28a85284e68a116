// DeviceImpl: the OpenCL side of a Device (context, in-order profiling queue, launch parameters, and the
// program and kernel caches, which live and die with the context).
#pragma once

#include <CL/opencl.hpp>

#include <cstddef>
#include <map>
#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::detail {

/// Launch shapes for one device, chosen by device type; DUPLEXFIT_WG_SIZE, DUPLEXFIT_CHUNK,
/// DUPLEXFIT_LANES and DUPLEXFIT_REDUCTIONS (chunk|group) override them (the values show up in
/// benchmark headers). Tests use the overrides to run the GPU-style kernels on a CPU device.
struct LaunchParams {
  std::size_t workGroup = 64;   ///< local size of every launch (element-wise and group reductions)
  std::size_t chunk = 512;      ///< elements per work-item in the barrier-free chunk kernels
  std::size_t lanes = 16;       ///< work-items per row in spmv_csr_group
  std::size_t groups = 256;     ///< work-groups of the group reductions
  bool chunkReductions = true;  ///< CPU style: chunk reductions and fused row-per-item SpMV
  bool fieldVector = true;      ///< float field evaluation by the SIMD eval_field_*_v8 kernels (CPU devices)
  int fieldWidth = 8;           ///< their centres a step, 8 or 16 (FIELD_WIDTH in the field program)
  /// The SIMD kernels sum the levels with large weights in double (DPX_COARSE_DOUBLE in the float field
  /// program): with fieldVector on a device with fp64; DUPLEXFIT_FIELD_COARSE=double|float overrides.
  bool fieldCoarseDouble = false;
  /// The SIMD kernels sum the coarse levels a tile of fieldWidth queries at a time (the _tile kernels):
  /// with fieldVector; DUPLEXFIT_FIELD_TILES=0|1 overrides.
  bool fieldTiles = false;
  DeviceTuning tuning() const;  ///< the public view (Device::tuning)
  std::string describe() const;
};

/// The programs duplexfit builds: name -> ordered kernel files (common.cl first).
const std::vector<std::pair<std::string, std::vector<std::string>>>& programTable();

class DeviceImpl {
 public:
  /// fp64Allowed: DeviceOptions::allowFp64 of the handle this serves (its launch parameters use no double
  /// where it is false).
  DeviceImpl(const cl::Device& device, const DeviceInfo& info, bool fp64Allowed);

  cl::Context& context() { return context_; }
  cl::CommandQueue& queue() { return queue_; }
  const cl::Device& device() const { return device_; }
  const DeviceInfo& info() const { return info_; }
  const LaunchParams& params() const { return params_; }

  /// The options a program is built with: "-cl-std=CL1.2" + DUPLEXFIT_CL_BUILD_OPTIONS + extra.
  std::string buildOptions(const std::string& extra) const;
  /// The full source of a program: defines (REAL, WG, CHUNK, LANES) then its files.
  std::string programSource(const std::string& program, Precision precision) const;
  /// Builds (or returns the cached) program. @throws BuildError with device, options and full log.
  cl::Program program(const std::string& program, Precision precision, const std::string& extraOptions = {});
  /// A cached kernel of a program built with the default options.
  cl::Kernel& kernel(const std::string& program, Precision precision, const std::string& kernelName);

  /// A scratch buffer of at least `bytes` (grown on demand, reused; for reduction partials).
  cl::Buffer& scratch(std::size_t bytes);

  /// Enqueues a 1-D launch; global is rounded up to a multiple of local. Checked.
  void launch(cl::Kernel& kernel, std::size_t global, std::size_t local, const char* name);

  /// Held around a cached kernel's argument setting, launch and result read where several host threads
  /// share this device (the field evaluations of meshes finished at once, finishSurfaces): a cached
  /// cl::Kernel's arguments are per kernel object, not per call.
  std::mutex& launchMutex() { return launchMutex_; }

 private:
  cl::Device device_;
  DeviceInfo info_;
  cl::Context context_;
  cl::CommandQueue queue_;
  LaunchParams params_;
  std::mutex mutex_;
  std::mutex launchMutex_;
  std::map<std::tuple<std::string, Precision, std::string>, cl::Program> programs_;
  std::map<std::tuple<std::string, Precision, std::string>, cl::Kernel> kernels_;
  cl::Buffer scratch_;
  std::size_t scratchBytes_ = 0;
};

[[noreturn]] void throwKernelArgError(cl_int status, const char* kernelName, cl_uint index);

/// Sets kernel argument i, checking the status (the message names the kernel and the argument).
template <typename T>
void setArg(cl::Kernel& kernel, cl_uint index, const T& value, const char* kernelName) {
  const cl_int status = kernel.setArg(index, value);
  if (status != CL_SUCCESS) {
    throwKernelArgError(status, kernelName, index);
  }
}

/// Sets all arguments in order.
template <typename... Args>
void setArgs(cl::Kernel& kernel, const char* kernelName, const Args&... args) {
  cl_uint i = 0;
  (setArg(kernel, i++, args, kernelName), ...);
}

}  // namespace duplexfit::detail
