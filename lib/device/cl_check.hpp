// Status checking for OpenCL calls: every call's status goes through DUPLEXFIT_CL_CHECK, which throws a
// DeviceError carrying the status, its name and the call text.
#pragma once

#include <string>

namespace duplexfit::detail {

/// "CL_OUT_OF_RESOURCES" etc. for an OpenCL status code.
const char* clErrorName(int status) noexcept;

/// Throws DeviceError("<call> failed: <name> (<status>)").
[[noreturn]] void throwClError(int status, const std::string& call);

}  // namespace duplexfit::detail

#define DUPLEXFIT_CL_CHECK(call)                                                    \
  do {                                                                              \
    const int duplexfit_status_ = static_cast<int>(call);                           \
    if (duplexfit_status_ != 0) ::duplexfit::detail::throwClError(duplexfit_status_, #call); \
  } while (false)
