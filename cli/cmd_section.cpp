// Placeholder: this command is being written (replaced by its module's implementation).
#include "commands.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kSectionValued = {};
const char* const kSectionHelp = "";
int cmdSection(Args&) { throw UsageError("section: not available yet"); }
}  // namespace duplexfit::cli
