// Placeholder: this command is being written (replaced by its module's implementation).
#include "commands.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kMeasureValued = {};
const std::vector<std::string> kCheckValued = {};
const char* const kMeasureHelp = "";
int cmdMeasure(Args&) { throw UsageError("measure: not available yet"); }
int cmdCheck(Args&) { throw UsageError("check: not available yet"); }
}  // namespace duplexfit::cli
