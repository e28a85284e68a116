// Placeholder: this command is being written (replaced by its module's implementation).
#include "commands.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kSliceValued = {};
const char* const kSliceHelp = "";
int cmdSlice(Args&) { throw UsageError("slice: not available yet"); }
}  // namespace duplexfit::cli
