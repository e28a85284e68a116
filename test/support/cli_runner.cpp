// Runs the duplexfit command-line tool and captures what it printed (cli_runner.hpp).
#include "cli_runner.hpp"

#include <sys/wait.h>

#include <cstdlib>

#include "temp_dir.hpp"

namespace duplexfit::testing {

CliRun runCommand(const std::string& command) {
  const TempDir capture("duplexfit-cli-run");
  const std::string out = capture.file("stdout.txt"), err = capture.file("stderr.txt");
  const std::string cmd = command + " > " + out + " 2> " + err;
  const int raw = std::system(cmd.c_str());
  CliRun r;
  r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  r.out = readFile(out);
  r.err = readFile(err);
  return r;
}

std::string cliPath() {
#ifdef DUPLEXFIT_CLI_PATH
  return DUPLEXFIT_CLI_PATH;
#else
  return {};
#endif
}

CliRun runCli(const std::string& args) { return runCommand(cliPath() + " " + args); }

}  // namespace duplexfit::testing
