// Runs the duplexfit command-line tool as a user would (through the shell) and captures its exit status,
// standard output and standard error.
#pragma once

#include <string>

#include "skip.hpp"

namespace duplexfit::testing {

/// What one run of a command gave.
struct CliRun {
  int status = -1;  ///< the exit status; -1 when the command did not exit normally (a signal)
  std::string out;  ///< standard output
  std::string err;  ///< standard error
};

/// Runs `command` with /bin/sh, its standard output and error redirected to files in a private temporary
/// folder that is removed afterwards (so nothing appears in the test's own folders).
CliRun runCommand(const std::string& command);

/// The duplexfit CLI binary the tests run, or "" when it is not built (DUPLEXFIT_BUILD_CLI=OFF).
std::string cliPath();

/// Runs `duplexfit ARGS` (ARGS as a shell would split it).
CliRun runCli(const std::string& args);

}  // namespace duplexfit::testing

/// At the top of a test case that runs the CLI: skips the case when the CLI is not built.
#define DUPLEXFIT_REQUIRE_CLI()                                                      \
  do {                                                                               \
    if (::duplexfit::testing::cliPath().empty()) {                                   \
      DUPLEXFIT_SKIP("the duplexfit CLI is not built (DUPLEXFIT_BUILD_CLI=OFF)");    \
    }                                                                                \
  } while (false)
