// What every duplexfit subcommand shares besides its CLI11 options (options.hpp): the usage error, the
// number-list parser and the exit codes.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

namespace duplexfit::cli {

/// A usage mistake: the CLI prints it and exits with status 1.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};


/// A comma-separated list of finite numbers ("0.1,-0.05"), for option --`option`.
inline std::vector<double> parseNumberList(const std::string& text, const char* option) {
  if (text.empty()) throw UsageError(std::string("option --") + option + " needs at least one value");
  std::vector<double> out;
  std::size_t begin = 0;
  while (begin <= text.size()) {
    const std::size_t end = std::min(text.find(',', begin), text.size());
    const std::string item = text.substr(begin, end - begin);
    char* stop = nullptr;
    const double v = std::strtod(item.c_str(), &stop);
    if (item.empty() || stop == item.c_str() || *stop != '\0' || !std::isfinite(v)) {
      throw UsageError(std::string("option --") + option + ": '" + item + "' is not a number");
    }
    out.push_back(v);
    begin = end + 1;
  }
  return out;
}

/// Exit codes (README): 1 usage, 2 I/O, 3 device, 4 numerical failure with --strict.
constexpr int kUsage = 1, kIo = 2, kDevice = 3, kNumerical = 4, kOutOfMemory = 5;

}  // namespace duplexfit::cli
