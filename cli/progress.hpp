// The CLI's Interrupter: progress lines, fit events and, for every stage that reports how far it is and
// lasts more than a second, its fraction and an ETA on stderr (nothing with --quiet). On a terminal the
// fraction is one bar redrawn in place; otherwise (a log file, a pipe) a plain line at every tenth.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "signals.hpp"
#include "timer.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/interrupter.hpp"

namespace duplexfit::cli {

/// "12.3 s", "4 min 05 s", "1 h 02 min".
inline std::string formatDuration(double seconds) {
  std::ostringstream s;
  if (!(seconds >= 0.0)) seconds = 0.0;
  if (seconds < 60.0) {
    s.setf(std::ios::fixed);
    s.precision(seconds < 10.0 ? 1 : 0);
    s << seconds << " s";
  } else if (seconds < 3600.0) {
    const long m = static_cast<long>(seconds / 60.0), sec = static_cast<long>(seconds) % 60;
    s << m << " min " << (sec < 10 ? "0" : "") << sec << " s";
  } else {
    const long h = static_cast<long>(seconds / 3600.0), m = (static_cast<long>(seconds) % 3600) / 60;
    s << h << " h " << (m < 10 ? "0" : "") << m << " min";
  }
  return s.str();
}

/// "fit 45% after 12.3 s, about 15 s left" (the ETA from 5% on: elapsed × (100 − p) / p).
inline std::string progressText(const std::string& stage, int percent, double elapsed) {
  std::string line = stage + " " + std::to_string(percent) + "% after " + formatDuration(elapsed);
  if (percent >= 5 && percent < 100) {  // below 5% the rate says little yet
    line += ", about " + formatDuration(elapsed * (100.0 - percent) / percent) + " left";
  }
  return line;
}

class StderrProgress : public Interrupter {
 public:
  using Clock = std::chrono::steady_clock;

  /// `terminal`: draw a bar in place (default: whether stderr is a terminal; DUPLEXFIT_PROGRESS=plain
  /// forces the plain lines, =bar the bar).
  explicit StderrProgress(bool quiet) : StderrProgress(quiet, defaultTerminal()) {}
  StderrProgress(bool quiet, bool terminal) : quiet_(quiet), terminal_(terminal) {}
  ~StderrProgress() override { clearBar(); }
  StderrProgress(const StderrProgress&) = delete;
  StderrProgress& operator=(const StderrProgress&) = delete;

  void start(const char* name) override {
    setLastStage(name);
    clearBar();
    stages_.push_back(Stage{name != nullptr ? name : "", Clock::now()});
  }
  void end() override {
    if (stages_.empty()) return;
    const Stage s = stages_.back();
    stages_.pop_back();
    if (!quiet_ && s.shown) {
      clearBar();
      std::cerr << s.name << " done in " << formatDuration(seconds(s.begin)) << std::endl;
    }
  }
  /// Shows the percent (when known) of the current stage; true once a stop signal arrived (signals.hpp;
  /// only the commands that install the handlers get one).
  bool wasInterrupted(int percent) override {
    if (!quiet_ && percent >= 0 && !stages_.empty()) show(stages_.back(), std::min(percent, 100));
    return stopSignal() != 0;
  }
  void message(const std::string& line) override {
    if (quiet_) return;
    clearBar();
    std::cerr << line << std::endl;
  }
  void fitEvent(const FitEvent& e) override {
    if (quiet_) return;
    clearBar();
    const char* stage = fitStageName(e.stage);
    if (e.stage == FitStage::Solve && e.iteration > 0) {
      if (e.level > 0) std::cerr << "  level " << e.level << "/" << e.levels;
      std::cerr << "  CG iteration " << e.iteration << "  residual " << e.residual << "\n";
    } else if (e.level > 0) {
      std::cerr << "level " << e.level << "/" << e.levels << ": " << stage
                << (e.message.empty() ? "" : " (" + e.message + ")") << "\n";
    } else if (e.stage == FitStage::Errors) {
      std::cerr << "measuring E0 and E_delta at the input and offset points\n";
    } else {
      std::cerr << stage << (e.message.empty() ? "" : ": " + e.message) << "\n";
    }
  }

 private:
  struct Stage {
    std::string name;
    Clock::time_point begin;
    int lastPercent = -1;  ///< last shown
    double lastShown = 0.0;
    bool shown = false;
  };

  static bool defaultTerminal() {
    if (const char* mode = std::getenv("DUPLEXFIT_PROGRESS")) {
      const std::string m = mode;
      if (m == "plain") return false;
      if (m == "bar") return true;
    }
    return isatty(STDERR_FILENO) != 0;
  }
  static double seconds(Clock::time_point since) {
    return std::chrono::duration<double>(Clock::now() - since).count();
  }

  void show(Stage& s, int percent) {
    const double elapsed = seconds(s.begin);
    if (elapsed < 1.0) return;  // short stages stay silent
    if (terminal_) {
      if (percent == s.lastPercent && elapsed - s.lastShown < 1.0) return;
      constexpr int kWidth = 24;
      const int filled = percent * kWidth / 100;
      std::cerr << "\r\033[K" << s.name << " [" << std::string(static_cast<std::size_t>(filled), '#')
                << std::string(static_cast<std::size_t>(kWidth - filled), '.') << "] "
                << progressText("", percent, elapsed).substr(1) << std::flush;
      barActive_ = true;
    } else {
      // A line at every tenth, or every 30 s while the percent stands still.
      const bool nextTenth = percent / 10 > s.lastPercent / 10 || (s.lastPercent < 0 && percent > 0);
      if (!nextTenth && elapsed - s.lastShown < 30.0) return;
      std::cerr << progressText(s.name, percent, elapsed) << "\n";
    }
    s.lastPercent = percent;
    s.lastShown = elapsed;
    s.shown = true;
  }
  void clearBar() {
    if (!barActive_) return;
    std::cerr << "\r\033[K" << std::flush;
    barActive_ = false;
  }

  bool quiet_;
  bool terminal_;
  bool barActive_ = false;
  std::vector<Stage> stages_;
};

/// Opens --device SPEC (empty: the default device) and logs "device: ...".
inline Device openDevice(const std::string& spec, Interrupter& log) {
  const Device d = spec.empty() ? Device::openDefault() : Device::open(spec);
  log.message("device: " + d.description());
  return d;
}

}  // namespace duplexfit::cli
