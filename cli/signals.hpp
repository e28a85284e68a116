// Stop signals of the commands that write output sets (fit, mesh, slice, section, denoise, normals):
// the first SIGINT, SIGTERM or SIGHUP is recorded and the default action restored (a second one kills at
// once); the command's Interrupter then reports an interruption, the running operation throws Cancelled
// at its next poll, the staging folder is removed on the way out and main() exits with 128 + the signal.
#pragma once

#include <string>

namespace duplexfit::cli {

/// Installs the handlers (idempotent).
void installStopSignals();
/// The first stop signal received (SIGINT, SIGTERM, SIGHUP), or 0.
int stopSignal() noexcept;
/// "SIGINT", "SIGTERM", "SIGHUP" or "a signal".
const char* stopSignalName(int signal) noexcept;
/// The name of the last stage a command's Interrupter was told of (start()), "" before any: named in the
/// out-of-memory message.
const std::string& lastStage() noexcept;
void setLastStage(const char* name);

}  // namespace duplexfit::cli
