// The one stopwatch of the CLI commands (stage times in their JSON output and progress lines).
#pragma once

#include <chrono>

namespace duplexfit::cli {

/// Seconds since construction (or the last restart()).
class Timer {
 public:
  Timer() : start_(std::chrono::steady_clock::now()) {}
  void restart() { start_ = std::chrono::steady_clock::now(); }
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_;
};

}  // namespace duplexfit::cli
