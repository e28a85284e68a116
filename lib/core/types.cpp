// String conversions for the basic enums in types.hpp.
#include "duplexfit/types.hpp"

#include <algorithm>
#include <cctype>
#include <string>

#include "duplexfit/error.hpp"

namespace duplexfit {

const char* precisionName(Precision precision) noexcept {
  return precision == Precision::Double ? "double" : "float";
}

Precision parsePrecision(const char* text) {
  std::string s = text != nullptr ? text : "";
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (s == "float" || s == "single" || s == "f32") return Precision::Float;
  if (s == "double" || s == "f64") return Precision::Double;
  throw InvalidArgument("unknown precision '" + std::string(text != nullptr ? text : "") +
                        "' (expected float or double)");
}

}  // namespace duplexfit
