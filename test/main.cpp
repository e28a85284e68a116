// Test runner: doctest with a process-wide OpenCL device selected by --device=SPEC or DUPLEXFIT_DEVICE,
// and the skip report (support/skip.hpp): a "SKIPPED:" line per skipped test case, a count at the end, and
// exit status 77 (ctest's SKIP_RETURN_CODE) when every test case that ran skipped or none ran.
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
#include "skip.hpp"
#include "temp_dir.hpp"
#include "test_device.hpp"

namespace {

std::string g_spec;
bool g_specGiven = false;
bool g_runStarted = false;  // false for queries (--help, --list-test-cases, --count, ...)

// Tells the skip tally which test case runs.
struct SkipListener : doctest::IReporter {
  explicit SkipListener(const doctest::ContextOptions& /*options*/) {}
  void report_query(const doctest::QueryData& /*data*/) override {}
  void test_run_start() override { g_runStarted = true; }
  void test_run_end(const doctest::TestRunStats& /*stats*/) override {}
  void test_case_start(const doctest::TestCaseData& tc) override { duplexfit::testing::testCaseStarted(tc.m_name); }
  void test_case_reenter(const doctest::TestCaseData& /*tc*/) override {}
  void test_case_end(const doctest::CurrentTestCaseStats& /*stats*/) override { duplexfit::testing::testCaseEnded(); }
  void test_case_exception(const doctest::TestCaseException& /*e*/) override {}
  void subcase_start(const doctest::SubcaseSignature& /*s*/) override {}
  void subcase_end() override {}
  void log_assert(const doctest::AssertData& /*a*/) override {}
  void log_message(const doctest::MessageData& /*m*/) override {}
  void test_case_skipped(const doctest::TestCaseData& /*tc*/) override {}
};

}  // namespace

REGISTER_LISTENER("duplexfit-skips", 1, SkipListener);

namespace duplexfit::testing {

bool deviceRequired() {
  const char* env = std::getenv("DUPLEXFIT_REQUIRE_DEVICE");
  return env != nullptr && std::string(env) == "1";
}

const Device& openclOrReferenceDevice() {
  static const Device ref = Device::reference();
  const Device* d = openclTestDevice();
  return d != nullptr ? *d : ref;
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
  const int result = context.run();
  if (context.shouldExit() || !g_runStarted) return result;
  duplexfit::testing::finishScratchDirs(result == 0);
  const duplexfit::testing::SkipTally& tally = duplexfit::testing::skipTally();
  std::cout << duplexfit::testing::skipSummary();
  if (result != 0) return result;
  if (tally.ran == 0 || tally.skipped == tally.ran) {
    std::cout << "[duplexfit tests] " << (tally.ran == 0 ? "no test case ran" : "every test case that ran skipped")
              << ": exit status " << duplexfit::testing::kSkipExitCode << " (skipped)" << std::endl;
    return duplexfit::testing::kSkipExitCode;
  }
  return result;
}
