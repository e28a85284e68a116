// Where the tests find their data (data.hpp).
#include "data.hpp"

#include <cstdlib>

namespace fs = std::filesystem;

namespace duplexfit::testing {

fs::path sharedDataLocation() {
  const char* env = std::getenv("DUPLEXFIT_SHARED_DATA");
  if (env != nullptr && *env != '\0') return fs::path(env).lexically_normal();
  return (fs::path(DUPLEXFIT_SOURCE_DIR) / ".." / "shared" / "data").lexically_normal();
}

std::string findSharedData() {
  const fs::path dir = sharedDataLocation();
  return fs::is_directory(dir / "clouds") ? dir.string() : std::string();
}

std::string repoDataDir() { return (fs::path(DUPLEXFIT_SOURCE_DIR) / "data").lexically_normal().string(); }

std::string repoTestDataDir() {
  return (fs::path(DUPLEXFIT_SOURCE_DIR) / "test" / "data").lexically_normal().string();
}

bool ciRun() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::string(ci) == "true";
}

}  // namespace duplexfit::testing
