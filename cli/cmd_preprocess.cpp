// Placeholder: this command is being written (replaced by its module's implementation).
#include "commands.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kDenoiseValued = {};
const std::vector<std::string> kNormalsValued = {};
const char* const kPreprocessHelp = "";
int cmdDenoise(Args&) { throw UsageError("denoise: not available yet"); }
int cmdNormals(Args&) { throw UsageError("normals: not available yet"); }
}  // namespace duplexfit::cli
