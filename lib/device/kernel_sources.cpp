// Lookup of embedded kernel sources, with the DUPLEXFIT_KERNEL_DIR development override.
#include "device/kernel_sources.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "duplexfit/error.hpp"

namespace duplexfit::detail {

std::string kernelSource(const std::string& name) {
  if (const char* dir = std::getenv("DUPLEXFIT_KERNEL_DIR"); dir != nullptr && *dir != '\0') {
    const std::string path = std::string(dir) + "/" + name + ".cl";
    std::ifstream in(path, std::ios::binary);
    if (!in) throw DeviceError("DUPLEXFIT_KERNEL_DIR is set but " + path + " cannot be read");
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  for (const EmbeddedKernel& k : embeddedKernels()) {
    if (name == k.name) return std::string(k.data, k.size);
  }
  throw DeviceError("no embedded kernel source named '" + name + "'");
}

}  // namespace duplexfit::detail
