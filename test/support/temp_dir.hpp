// Temporary folders and whole-file access for the tests: a self-removing fresh folder, a named scratch
// folder kept after the run for inspection, and reading or writing a file's bytes in one call.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace duplexfit::testing {

/// A fresh, empty folder <system temp>/<prefix>-<pid>-<n>, removed with its content on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& prefix = "duplexfit-test");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  /// The path of `name` inside the folder.
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }
  const std::filesystem::path& path() const { return path_; }
  /// Names of the entries in the folder, sorted.
  std::vector<std::string> entries() const;

 private:
  std::filesystem::path path_;
};

/// A fresh, empty folder <system temp>/<group>-<pid>/<name> (emptied if it exists). The group folders stay
/// after a failing run so that its files can be looked at; after a run that passed, the test runner removes
/// them (finishScratchDirs).
std::filesystem::path scratchDir(const std::string& group, const std::string& name);

/// At the end of the run: removes every group folder scratchDir made when `passed` and
/// DUPLEXFIT_KEEP_SCRATCH is not 1; otherwise names them on stderr. (The CLI suites alone left about 150 MB
/// in the temp folder each run.)
void finishScratchDirs(bool passed);

/// The bytes of a file; "" when it cannot be read.
std::string readFile(const std::filesystem::path& path);

/// Writes `bytes` as the whole file (removed first); false when the write failed.
bool writeFile(const std::filesystem::path& path, const std::string& bytes);

}  // namespace duplexfit::testing
