// The exception hierarchy of duplexfit. Errors are exceptions; numerical outcomes (a CG solve that did not
// converge) are reported in result structs instead (see linalg.hpp SolveStats).
#pragma once

#include <stdexcept>
#include <string>

namespace duplexfit {

/// Base of every exception the library throws.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad input data or options; the message names the argument, element or field.
class InvalidArgument : public Error {
 public:
  using Error::Error;
};

/// A file could not be read or written, or its content is malformed.
class IoError : public Error {
 public:
  using Error::Error;
};

/// An OpenCL call failed, no device matched a spec, or the device cannot do what was asked
/// (no fp64, buffer larger than its max allocation).
class DeviceError : public Error {
 public:
  /// @param message full human-readable message
  /// @param status  the OpenCL status code (0 when the error is not from an OpenCL call)
  /// @param call    the OpenCL call text, e.g. "clEnqueueNDRangeKernel(spmv_csr_row)"
  explicit DeviceError(const std::string& message, int status = 0, std::string call = {})
      : Error(message), status_(status), call_(std::move(call)) {}
  int status() const noexcept { return status_; }
  const std::string& call() const noexcept { return call_; }

 private:
  int status_;
  std::string call_;
};

/// An OpenCL program failed to build. what() holds device, options and the full build log.
class BuildError : public DeviceError {
 public:
  BuildError(const std::string& message, std::string log, int status)
      : DeviceError(message, status, "clBuildProgram"), log_(std::move(log)) {}
  const std::string& log() const noexcept { return log_; }

 private:
  std::string log_;
};

/// Thrown when an Interrupter asked to cancel a long operation.
class Cancelled : public Error {
 public:
  using Error::Error;
};

}  // namespace duplexfit
