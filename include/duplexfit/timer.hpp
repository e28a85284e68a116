// The one stopwatch of the library and the CLI: stage times in reports, JSON output and progress lines.
#pragma once

#include <chrono>

namespace duplexfit {

using SteadyClock = std::chrono::steady_clock;

/// Seconds from t to now.
inline double secondsSince(SteadyClock::time_point t) {
  return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

/// Seconds since construction (or the last restart()).
class Timer {
 public:
  Timer() : start_(SteadyClock::now()) {}
  void restart() { start_ = SteadyClock::now(); }
  double seconds() const { return secondsSince(start_); }

 private:
  SteadyClock::time_point start_;
};

}  // namespace duplexfit
