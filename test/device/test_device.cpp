// Device specs, enumeration, selection errors, precision checks and vector round trips.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>

#include "duplexfit/device.hpp"
#include "duplexfit/error.hpp"
#include "device/device_impl.hpp"
#include "duplexfit/linalg.hpp"
#include "test_device.hpp"

using namespace duplexfit;

TEST_SUITE("device") {
  TEST_CASE("device spec: parses every form of the syntax") {
    CHECK(DeviceSpec::parse("").kind == DeviceSpec::Kind::Default);
    CHECK(DeviceSpec::parse(" default ").kind == DeviceSpec::Kind::Default);
    CHECK(DeviceSpec::parse("ref").kind == DeviceSpec::Kind::Reference);
    CHECK(DeviceSpec::parse("REF").kind == DeviceSpec::Kind::Reference);
    const DeviceSpec idx = DeviceSpec::parse("1:2");
    CHECK(idx.kind == DeviceSpec::Kind::Indices);
    CHECK(idx.platform == 1);
    CHECK(idx.device == 2);
    CHECK(idx.toString() == "1:2");
    const DeviceSpec gpu = DeviceSpec::parse("GPU");
    CHECK(gpu.kind == DeviceSpec::Kind::Type);
    CHECK(gpu.type == DeviceType::Gpu);
    CHECK(DeviceSpec::parse("cpu").type == DeviceType::Cpu);
    const DeviceSpec name = DeviceSpec::parse("PoCL");
    CHECK(name.kind == DeviceSpec::Kind::Name);
    CHECK(name.name == "pocl");
    CHECK_THROWS_AS(DeviceSpec::parse("1:"), InvalidArgument);
    CHECK_THROWS_AS(DeviceSpec::parse(":0"), InvalidArgument);
    CHECK_THROWS_AS(DeviceSpec::parse("0:1:2"), InvalidArgument);
  }

  TEST_CASE("device spec: DUPLEXFIT_DEVICE selects the device") {
    const char* old = std::getenv("DUPLEXFIT_DEVICE");
    const std::string saved = old != nullptr ? old : "";
    setenv("DUPLEXFIT_DEVICE", "ref", 1);
    CHECK(DeviceSpec::fromEnvironment().kind == DeviceSpec::Kind::Reference);
    CHECK(Device::openDefault().isReference());
    unsetenv("DUPLEXFIT_DEVICE");
    CHECK(DeviceSpec::fromEnvironment().kind == DeviceSpec::Kind::Default);
    if (old != nullptr) setenv("DUPLEXFIT_DEVICE", saved.c_str(), 1);
  }

  TEST_CASE("device: the reference device is always available and has fp64") {
    const Device ref = Device::reference();
    CHECK(ref.isReference());
    CHECK(ref.kind() == DeviceKind::Reference);
    CHECK(ref.info().spec == "ref");
    CHECK(ref.supportsDouble());
    CHECK_NOTHROW(ref.requirePrecision(Precision::Double));
    CHECK(Device::open("ref").isReference());
  }

  TEST_CASE("device: a spec that matches nothing lists the devices that exist") {
    try {
      (void)Device::open("no-such-device-xyz");
      FAIL("expected DeviceError");
    } catch (const DeviceError& e) {
      const std::string what = e.what();
      CHECK(what.find("no-such-device-xyz") != std::string::npos);
      CHECK(what.find("available devices") != std::string::npos);
      CHECK(what.find("ref") != std::string::npos);
      for (const DeviceInfo& info : Device::enumerate()) CHECK(what.find(info.spec) != std::string::npos);
    }
    CHECK_THROWS_AS((void)Device::open("77:3"), DeviceError);
  }

  TEST_CASE("device: OpenCL enumeration describes the test device") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const auto all = Device::enumerate();
    REQUIRE(!all.empty());
    bool found = false;
    for (const DeviceInfo& info : all) {
      CHECK(!info.name.empty());
      CHECK(info.spec == std::to_string(info.platformIndex) + ":" + std::to_string(info.deviceIndex));
      CHECK(info.maxAllocBytes > 0);
      CHECK(info.globalMemBytes >= info.maxAllocBytes);
      found = found || info.spec == dev.info().spec;
    }
    CHECK(found);
    // Reopening by index, by type and by a name substring gives the same device.
    CHECK(Device::open(dev.info().spec).info().name == dev.info().name);
    CHECK(Device::open(deviceTypeName(dev.info().type)).info().type == dev.info().type);
    CHECK(Device::open(dev.info().name.substr(0, 6)).info().spec.size() >= 3);
  }

  TEST_CASE("device: double precision is a clear error where fp64 is unavailable") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    DeviceOptions options;
    options.allowFp64 = false;
    const Device noFp64 = Device::open(dev.info().spec, options);
    CHECK_FALSE(noFp64.supportsDouble());
    try {
      DeviceVector v(noFp64, 10, Precision::Double);
      FAIL("expected DeviceError");
    } catch (const DeviceError& e) {
      CHECK(std::string(e.what()).find("double") != std::string::npos);
      CHECK(std::string(e.what()).find(dev.info().name) != std::string::npos);
    }
    CHECK_NOTHROW(DeviceVector(noFp64, 10, Precision::Float));
    // Nor are a float field's coarse levels summed in double through it.
    CHECK_FALSE(noFp64.tuning().fieldCoarseDouble);
    CHECK(noFp64.tuning().describe().find("+double") == std::string::npos);
    // Its float field program has no double code at all (the launch parameters know the option), where a
    // handle that may use fp64 on a CPU device with it sums the coarse levels in double.
    CHECK(noFp64.impl()->programSource("field", Precision::Float).find("#define DPX_COARSE_DOUBLE 1") == std::string::npos);
    if (dev.info().fp64 && dev.tuning().fieldVector && std::getenv("DUPLEXFIT_FIELD_COARSE") == nullptr) {
      CHECK(dev.impl()->programSource("field", Precision::Float).find("#define DPX_COARSE_DOUBLE 1") != std::string::npos);
    }
  }

  TEST_CASE("device: a buffer above the max allocation is refused with sizes in the message") {
    for (const bool opencl : {false, true}) {
      Device base = Device::reference();
      if (opencl) {
        const Device* d = testing::openclTestDevice();
        if (d == nullptr) continue;
        base = *d;
      }
      DeviceOptions options;
      options.maxAllocBytes = 1 << 20;
      const Device capped = Device::open(base.info().spec, options);
      CHECK(capped.maxAllocBytes() == (1u << 20));
      CHECK_NOTHROW(DeviceVector(capped, 1000, Precision::Float));
      try {
        DeviceVector v(capped, 1 << 20, Precision::Float);
        FAIL("expected DeviceError");
      } catch (const DeviceError& e) {
        CHECK(std::string(e.what()).find("MiB") != std::string::npos);
      }
    }
  }

  TEST_CASE("device vector: upload and download round trip on every device, n = 0 and n = 1") {
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    for (const Device& device : devices) {
      for (const Precision p : {Precision::Float, Precision::Double}) {
        if (!device.supportsDouble() && p == Precision::Double) continue;
        for (const int n : {0, 1, 7, 1000}) {
          CAPTURE(n);
          Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(n, -1.5, 2.25);
          DeviceVector v = DeviceVector::upload(device, x, p);
          CHECK(v.size() == static_cast<std::size_t>(n));
          CHECK(v.precision() == p);
          CHECK(v.download().size() == n);
          DeviceVector c = v.clone();
          v.fill(3.0);
          CHECK(c.download().size() == n);
          if (n == 0) continue;
          CHECK((c.download() - x).cwiseAbs().maxCoeff() <= 1e-6);
          CHECK(v.download().minCoeff() == 3.0);
          CHECK(v.download().maxCoeff() == 3.0);
        }
      }
    }
  }
}
