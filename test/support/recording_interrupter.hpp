// An Interrupter for tests: records every event, message and poll, and interrupts when `stopWhen` says so.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "duplexfit/interrupter.hpp"

namespace duplexfit::testing {

class RecordingInterrupter : public Interrupter {
 public:
  std::vector<FitEvent> events;     ///< fitEvent() calls, in order
  std::vector<std::string> lines;   ///< message() calls
  std::vector<int> percents;        ///< wasInterrupted() arguments
  std::vector<std::string> started; ///< start() names
  /// Polled by wasInterrupted() after the percent is recorded; empty: never interrupt.
  std::function<bool(const RecordingInterrupter&)> stopWhen;

  void start(const char* name) override { started.emplace_back(name != nullptr ? name : ""); }
  bool wasInterrupted(int percent) override {
    percents.push_back(percent);
    return stopWhen && stopWhen(*this);
  }
  void fitEvent(const FitEvent& event) override { events.push_back(event); }
  void message(const std::string& line) override { lines.push_back(line); }
};

}  // namespace duplexfit::testing
