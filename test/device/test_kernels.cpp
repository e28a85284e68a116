// Every embedded kernel program builds on the test device with -Werror; build failures carry the log.
#include <doctest/doctest.h>

#include <cstdlib>
#include <set>
#include <string>

#include "device/device_impl.hpp"
#include "device/kernel_sources.hpp"
#include "duplexfit/error.hpp"
#include "test_device.hpp"

using namespace duplexfit;

TEST_SUITE("device") {
  TEST_CASE("kernels: every kernels/*.cl file is embedded and used by a program") {
    std::set<std::string> embedded;
    for (const auto& k : detail::embeddedKernels()) {
      CHECK(k.size > 0);
      CHECK(std::string(k.data).size() == k.size);
      embedded.insert(k.name);
    }
    CHECK(embedded.count("common") == 1);
    std::set<std::string> used;
    for (const auto& [name, files] : detail::programTable()) {
      for (const auto& f : files) {
        CHECK(embedded.count(f) == 1);
        used.insert(f);
      }
    }
    CHECK(used == embedded);
    CHECK_THROWS_AS(detail::kernelSource("no_such_kernel"), DeviceError);
  }

  TEST_CASE("kernels: every program builds with -Werror in float and double") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    for (const auto& [name, files] : detail::programTable()) {
      for (const Precision p : {Precision::Float, Precision::Double}) {
        if (p == Precision::Double && !dev.supportsDouble()) continue;
        CAPTURE(name);
        CAPTURE(precisionName(p));
        CHECK_NOTHROW(dev.impl()->program(name, p, "-Werror"));
      }
    }
    // The field program at both SIMD widths, whatever the device's own (16 centres a step on a CPU without
    // AVX-512 must not warn about the float16 ABI either).
    // With and without the coarse levels in double (DPX_COARSE_DOUBLE) where the device has fp64.
    for (const char* kernel : {"vector8", "vector16"}) {
      for (const char* coarse : {"float", "double"}) {
        if (std::string(coarse) == "double" && !dev.info().fp64) continue;
        CAPTURE(kernel);
        CAPTURE(coarse);
        setenv("DUPLEXFIT_FIELD_KERNEL", kernel, 1);
        setenv("DUPLEXFIT_FIELD_COARSE", coarse, 1);
        const Device d = Device::open(dev.info().spec);
        unsetenv("DUPLEXFIT_FIELD_KERNEL");
        unsetenv("DUPLEXFIT_FIELD_COARSE");
        CHECK(d.tuning().fieldCoarseDouble == (std::string(coarse) == "double"));
        CHECK_NOTHROW(d.impl()->program("field", Precision::Float, "-Werror"));
      }
    }
  }

  TEST_CASE("kernels: a build failure reports device, options and the build log") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    try {
      (void)dev.impl()->program("blas1", Precision::Float, "-Dreal=(");
      FAIL("expected BuildError");
    } catch (const BuildError& e) {
      const std::string what = e.what();
      CHECK(what.find(dev.info().name) != std::string::npos);
      CHECK(what.find("-Dreal=(") != std::string::npos);
      CHECK(what.find("build log") != std::string::npos);
      CHECK(!e.log().empty());
    }
  }
}
