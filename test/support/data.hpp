// Where the tests find their data: the shared data folder (../shared/data next to the repository, or
// $DUPLEXFIT_SHARED_DATA) and the repository's own data/ folder; DUPLEXFIT_SHARED_DATA_DIR(var) skips a
// test case (or fails it in CI) when the shared data is missing.
#pragma once

#include <filesystem>
#include <string>

#include "skip.hpp"

namespace duplexfit::testing {

/// Where the shared test data is looked for: $DUPLEXFIT_SHARED_DATA when set and not empty, else
/// <source>/../shared/data (normalised).
std::filesystem::path sharedDataLocation();

/// sharedDataLocation() when it holds the clouds/ folder, else "".
std::string findSharedData();

/// The repository's data/ folder (the small example clouds).
std::string repoDataDir();

/// The repository's test/data/ folder (small meshes of regression tests; test/data/README.md).
std::string repoTestDataDir();

/// Whether this is a CI run (CI=true): missing shared data then fails instead of skipping.
bool ciRun();

}  // namespace duplexfit::testing

/// At the top of a test case that reads the shared data: binds `var` (std::string, the folder), or fails
/// (CI=true) or skips the case (DUPLEXFIT_SKIP) when the data is missing.
#define DUPLEXFIT_SHARED_DATA_DIR(var)                                                                   \
  const std::string var = ::duplexfit::testing::findSharedData();                                       \
  if (var.empty()) {                                                                                     \
    if (::duplexfit::testing::ciRun()) {                                                                 \
      FAIL("shared test data missing: " << ::duplexfit::testing::sharedDataLocation().string());         \
    }                                                                                                    \
    DUPLEXFIT_SKIP("shared test data not found at " << ::duplexfit::testing::sharedDataLocation().string() \
                                                    << " (DUPLEXFIT_SHARED_DATA sets the folder)");      \
  }                                                                                                      \
  static_assert(true, "")
