// Output staging for the commands that write several files: everything goes to a temporary folder inside
// the output folder first, commit() moves each entry into place, and the destructor removes whatever is
// left, so that a failed run leaves no partial output.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>
#include <vector>

#include "duplexfit/error.hpp"

namespace duplexfit::cli {

class Staging {
 public:
  /// Creates the output folder (and parents) and the staging folder inside it.
  /// @throws IoError when either cannot be created.
  explicit Staging(const std::filesystem::path& outDir) : outDir_(outDir) {
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::create_directories(outDir_, ec);
    if (ec || !fs::is_directory(outDir_)) {
      throw IoError(outDir_.string() + ": cannot create the output folder (" + ec.message() + ")");
    }
    dir_ = outDir_ / (".duplexfit-tmp-" + std::to_string(getpid()));
    fs::remove_all(dir_, ec);
    fs::create_directory(dir_, ec);
    if (ec) throw IoError(outDir_.string() + ": the output folder is not writable (" + ec.message() + ")");
  }
  ~Staging() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  Staging(const Staging&) = delete;
  Staging& operator=(const Staging&) = delete;

  /// The staged path of output `name`; with `folder`, the folder is created.
  std::string path(const std::string& name, bool folder = false) {
    names_.push_back(name);
    if (folder) {
      std::error_code ec;
      std::filesystem::create_directory(dir_ / name, ec);
      if (ec) throw IoError((dir_ / name).string() + ": cannot create (" + ec.message() + ")");
    }
    return (dir_ / name).string();
  }
  /// Moves every staged entry into the output folder (a folder replaces an older one of that name).
  void commit() {
    namespace fs = std::filesystem;
    for (const std::string& n : names_) {
      std::error_code ec;
      if (fs::is_directory(dir_ / n)) fs::remove_all(outDir_ / n, ec);
      fs::rename(dir_ / n, outDir_ / n, ec);
      if (ec) throw IoError((outDir_ / n).string() + ": cannot move the output into place (" + ec.message() + ")");
    }
  }

 private:
  std::filesystem::path outDir_, dir_;
  std::vector<std::string> names_;
};

}  // namespace duplexfit::cli
