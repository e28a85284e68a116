// The duplexfit subcommands; each returns the process exit status and throws for errors (main maps
// exceptions to exit codes).
#pragma once

#include "args.hpp"

namespace duplexfit::cli {

int cmdFit(Args& args);
int cmdMesh(Args& args);

/// Options that take a value, per command (everything else is a flag).
extern const std::vector<std::string> kFitValued;
extern const std::vector<std::string> kMeshValued;

}  // namespace duplexfit::cli
