// Access to the OpenCL kernel sources embedded at build time (cmake/EmbedKernelsScript.cmake).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace duplexfit::detail {

struct EmbeddedKernel {
  const char* name;  ///< file name without .cl, e.g. "spmv_csr"
  const char* data;  ///< NUL-terminated source
  std::size_t size;  ///< bytes without the NUL
};

/// Every embedded kernel file (generated).
const std::vector<EmbeddedKernel>& embeddedKernels();

/// The source of kernels/<name>.cl: from $DUPLEXFIT_KERNEL_DIR/<name>.cl when that variable is set
/// (development loop without rebuilding), else the embedded copy.
/// @throws DeviceError for an unknown name or an unreadable override file.
std::string kernelSource(const std::string& name);

}  // namespace duplexfit::detail
