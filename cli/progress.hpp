// The CLI's Interrupter: progress lines and fit events on stderr (nothing with --quiet).
#pragma once

#include <iostream>
#include <string>

#include "timer.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/interrupter.hpp"

namespace duplexfit::cli {

class StderrProgress : public Interrupter {
 public:
  explicit StderrProgress(bool quiet) : quiet_(quiet) {}
  void message(const std::string& line) override {
    if (!quiet_) std::cerr << line << std::endl;
  }
  void fitEvent(const FitEvent& e) override {
    if (quiet_) return;
    const char* stage = fitStageName(e.stage);
    if (e.stage == FitStage::Solve && e.iteration > 0) {
      std::cerr << "  level " << e.level << "/" << e.levels << "  CG iteration " << e.iteration << "  residual "
                << e.residual << "\n";
    } else if (e.level > 0) {
      std::cerr << "level " << e.level << "/" << e.levels << ": " << stage
                << (e.message.empty() ? "" : " (" + e.message + ")") << "\n";
    } else {
      std::cerr << stage << (e.message.empty() ? "" : ": " + e.message) << "\n";
    }
  }

 private:
  bool quiet_;
};

/// Opens --device SPEC (empty: the default device) and logs "device: ...".
inline Device openDevice(const std::string& spec, Interrupter& log) {
  const Device d = spec.empty() ? Device::openDefault() : Device::open(spec);
  log.message("device: " + d.description());
  return d;
}

}  // namespace duplexfit::cli
