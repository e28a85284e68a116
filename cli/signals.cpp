#include "signals.hpp"

#include <csignal>
#include <initializer_list>

namespace duplexfit::cli {
namespace {

volatile std::sig_atomic_t g_signal = 0;
std::string g_stage;

extern "C" void onStopSignal(int signal) {
  if (g_signal == 0) g_signal = signal;
  std::signal(signal, SIG_DFL);  // a second one stops the process at once
}

}  // namespace

void installStopSignals() {
  for (const int s : {SIGINT, SIGTERM, SIGHUP}) std::signal(s, onStopSignal);
}

int stopSignal() noexcept { return static_cast<int>(g_signal); }

const std::string& lastStage() noexcept { return g_stage; }

void setLastStage(const char* name) { g_stage = name != nullptr ? name : ""; }

const char* stopSignalName(int signal) noexcept {
  switch (signal) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    case SIGHUP: return "SIGHUP";
    default: return "a signal";
  }
}

}  // namespace duplexfit::cli
