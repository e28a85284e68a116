// Helpers of the libFuzzer targets: the readers take file names, so each input is written to a private
// temporary file first; the library's documented errors (InvalidArgument, IoError) are expected outcomes,
// anything else (another exception, a sanitizer report, a crash, a leak) is a finding.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "duplexfit/error.hpp"

namespace duplexfit::fuzz {

/// A temporary file named <tmp>/duplexfit-fuzz-<pid>-<tag><extension>, rewritten for every input.
class InputFile {
 public:
  InputFile(const std::string& tag, const std::string& extension) {
    const char* tmp = std::getenv("TMPDIR");
    path_ = std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/duplexfit-fuzz-" +
            std::to_string(static_cast<long>(getpid())) + "-" + tag + extension;
  }
  ~InputFile() { std::remove(path_.c_str()); }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  /// Writes the bytes (aborts when the file cannot be written: that is the harness failing, not the code).
  const std::string& write(const std::uint8_t* data, std::size_t size) const {
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    if (f == nullptr || (size > 0 && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) {
      std::perror(path_.c_str());
      std::abort();
    }
    return path_;
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// Runs body(); the library's own error types are fine, anything else escapes (libFuzzer reports it).
template <typename Body>
void expectLibraryErrorsOnly(Body&& body) {
  try {
    body();
  } catch (const InvalidArgument&) {
  } catch (const IoError&) {
  }
}

}  // namespace duplexfit::fuzz
