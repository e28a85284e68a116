// Test runner: doctest with a process-wide OpenCL device selected by --device=SPEC or DUPLEXFIT_DEVICE.
#define DOCTEST_CONFIG_IMPLEMENT
#include <doctest/doctest.h>

#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "test_device.hpp"

namespace {
std::string g_spec;
bool g_specGiven = false;
}  // namespace

namespace duplexfit::testing {

bool deviceRequired() {
  const char* env = std::getenv("DUPLEXFIT_REQUIRE_DEVICE");
  return env != nullptr && std::string(env) == "1";
}

const Device* openclTestDevice() {
  static std::optional<Device> device;
  static bool tried = false;
  if (!tried) {
    tried = true;
    try {
      Device d = g_specGiven ? Device::open(g_spec) : Device::openDefault();
      if (!d.isReference()) {
        device = d;
        std::cerr << "[duplexfit tests] OpenCL device: " << d.description() << "\n";
      } else {
        std::cerr << "[duplexfit tests] no OpenCL device selected (reference only)\n";
      }
    } catch (const Error& e) {
      std::cerr << "[duplexfit tests] cannot open the test device: " << e.what() << "\n";
    }
  }
  return device ? &*device : nullptr;
}

}  // namespace duplexfit::testing

int main(int argc, char** argv) {
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--device=", 9) == 0) {
      g_spec = argv[i] + 9;
      g_specGiven = true;
    } else {
      args.push_back(argv[i]);
    }
  }
  doctest::Context context(static_cast<int>(args.size()), args.data());
  return context.run();
}
