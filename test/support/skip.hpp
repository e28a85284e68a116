// Skips that the test run reports: a test case that cannot test what it is about (no OpenCL device, no
// shared data, the long tests not enabled, a case too heavy for the sanitizer build) says why and records
// the skip instead of returning as a silent pass. The runner (test/main.cpp) prints one "SKIPPED:" line
// per skipped case and a count at the end, and exits with kSkipExitCode when every case it ran skipped,
// which ctest (SKIP_RETURN_CODE) reports as "Skipped".
#pragma once

#include <doctest/doctest.h>

#include <sstream>
#include <string>
#include <vector>

namespace duplexfit::testing {

/// The exit status of a test run in which every test case that ran skipped (or none ran).
constexpr int kSkipExitCode = 77;

/// Marks the current test case as skipped: it tested nothing (use DUPLEXFIT_SKIP, which also returns).
void skipTestCase(const std::string& reason);

/// Records that a part of the current test case did not run; the case still counts as run.
void skipPart(const std::string& reason);

/// One recorded skip.
struct SkipEntry {
  std::string testCase;
  std::string reason;
  bool whole = true;  ///< the whole case skipped (else only a part of it)
};

/// The skips of the run so far.
struct SkipTally {
  unsigned ran = 0;      ///< test cases started
  unsigned skipped = 0;  ///< of them, skipped as a whole
  std::vector<SkipEntry> entries;
};

/// Runner side (called by test/main.cpp's doctest listener): a test case starts, and ends.
void testCaseStarted(const std::string& name);
void testCaseEnded();

const SkipTally& skipTally();

/// The summary printed at the end of a run: nothing when nothing skipped.
std::string skipSummary();

}  // namespace duplexfit::testing

/// Skips the rest of the current test case: prints "SKIPPED: <reason>", records the skip and returns.
/// `reason` may be a stream expression (DUPLEXFIT_SKIP("no data at " << dir)).
#define DUPLEXFIT_SKIP(reason)                                 \
  do {                                                         \
    std::ostringstream duplexfit_skip_reason_;                 \
    duplexfit_skip_reason_ << reason;                          \
    MESSAGE("SKIPPED: " << duplexfit_skip_reason_.str());      \
    ::duplexfit::testing::skipTestCase(duplexfit_skip_reason_.str()); \
    return;                                                    \
  } while (false)

/// Records that a part of the current test case is skipped (prints "SKIPPED (part): <reason>"); does not
/// return: the caller skips the part itself.
#define DUPLEXFIT_SKIP_PART(reason)                                  \
  do {                                                               \
    std::ostringstream duplexfit_skip_reason_;                       \
    duplexfit_skip_reason_ << reason;                                \
    MESSAGE("SKIPPED (part of this case): " << duplexfit_skip_reason_.str()); \
    ::duplexfit::testing::skipPart(duplexfit_skip_reason_.str());    \
  } while (false)
