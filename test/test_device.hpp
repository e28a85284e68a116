// The shared test device: one OpenCL device for the whole test run (programs build once per process),
// chosen by --device=SPEC or DUPLEXFIT_DEVICE, else the default. With DUPLEXFIT_REQUIRE_DEVICE=1 (set in CI)
// a missing OpenCL device fails the device tests instead of skipping them.
#pragma once

#include <doctest/doctest.h>

#include "duplexfit/device.hpp"
#include "skip.hpp"

namespace duplexfit::testing {

/// The OpenCL test device, or nullptr when none is available (then the caller skips or fails).
const Device* openclTestDevice();

/// Whether DUPLEXFIT_REQUIRE_DEVICE=1 is set.
bool deviceRequired();

/// The OpenCL test device, else the reference device (for fits that run on either).
const Device& openclOrReferenceDevice();

}  // namespace duplexfit::testing

/// At the top of a test case that needs the OpenCL device: binds `dev` (const Device&), or fails (CI,
/// DUPLEXFIT_REQUIRE_DEVICE=1) or skips the case (DUPLEXFIT_SKIP: local machine without OpenCL).
#define DUPLEXFIT_OPENCL_DEVICE(dev)                                                      \
  const ::duplexfit::Device* dev##_ptr_ = ::duplexfit::testing::openclTestDevice();       \
  if (dev##_ptr_ == nullptr) {                                                            \
    if (::duplexfit::testing::deviceRequired()) {                                         \
      FAIL("no OpenCL device available but DUPLEXFIT_REQUIRE_DEVICE=1");                  \
    }                                                                                     \
    DUPLEXFIT_SKIP("no OpenCL device");                                                   \
  }                                                                                       \
  const ::duplexfit::Device& dev = *dev##_ptr_
