// ResourceLimits: the machine's default budget, the --max-memory size parser and the refusal message.
#include "duplexfit/resources.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace duplexfit {

std::uint64_t peakResidentBytes() {
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) != 0 || usage.ru_maxrss < 0) return 0;
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024;  // Linux: kilobytes
}

std::uint64_t physicalMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page = sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return 0;
  return static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page);
}

std::uint64_t defaultMaxMemoryBytes() {
  const std::uint64_t physical = physicalMemoryBytes();
  std::uint64_t budget = physical > 0 ? physical / 4 * 3 : std::uint64_t{8} << 30;
  rlimit limit{};
  if (getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    budget = std::min<std::uint64_t>(budget, static_cast<std::uint64_t>(limit.rlim_cur));
  }
  return budget;
}

std::uint64_t ResourceLimits::bytes() const { return maxMemoryBytes > 0 ? maxMemoryBytes : defaultMaxMemoryBytes(); }

std::uint64_t parseByteSize(const std::string& text, const std::string& what) {
  const auto bad = [&](const std::string& why) {
    return InvalidArgument(what + ": '" + text + "' " + why +
                           " (a size such as 8G, 512M, 1.5GiB or a number of bytes, at least 1M)");
  };
  // The number: digits with at most one decimal point (no sign, exponent, hex, inf or nan).
  std::size_t i = 0;
  bool digits = false, point = false;
  for (; i < text.size(); ++i) {
    const char c = text[i];
    if (std::isdigit(static_cast<unsigned char>(c)) != 0) {
      digits = true;
    } else if (c == '.' && !point) {
      point = true;
    } else {
      break;
    }
  }
  if (!digits) throw bad("is not a size");
  const double number = std::strtod(text.substr(0, i).c_str(), nullptr);
  std::string unit = text.substr(i);
  if (!unit.empty() && unit.front() == ' ') unit.erase(0, 1);
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  double scale = 0.0;
  if (unit.empty() || unit == "b") {
    scale = 1.0;
  } else {
    const std::string suffix = unit.substr(1);
    if (suffix != "" && suffix != "b" && suffix != "ib") throw bad("has an unknown unit");
    const char u = unit.front();
    scale = u == 'k' ? 0x1p10 : u == 'm' ? 0x1p20 : u == 'g' ? 0x1p30 : u == 't' ? 0x1p40 : 0.0;
    if (scale == 0.0) throw bad("has an unknown unit");
  }
  const double bytes = std::floor(number * scale);
  if (!(bytes >= 0x1p20)) throw bad("is too small");
  if (!(bytes <= 0x1p60)) throw bad("is too large");
  return static_cast<std::uint64_t>(bytes);
}

std::string formatBytes(double bytes) {
  static const char* const kUnits[] = {"bytes", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  int u = 0;
  while (bytes >= 1024.0 && u < 6) {
    bytes /= 1024.0;
    ++u;
  }
  std::ostringstream s;
  s.precision(u == 0 ? 6 : 3);
  s << bytes << " " << kUnits[u];
  return s.str();
}

void requireMemory(const ResourceLimits& limits, const std::string& stage, double estimateBytes, const std::string& what,
                   const std::string& advice) {
  const std::uint64_t budget = limits.bytes();
  if (!(estimateBytes > static_cast<double>(budget))) return;
  const std::string message = stage + ": " + what + " needs about " + formatBytes(estimateBytes) +
                              ", more than --max-memory " + formatBytes(static_cast<double>(budget)) +
                              (limits.maxMemoryBytes == 0 ? " (the default, 75% of this machine's memory)" : "") + "; " +
                              advice + ", or raise --max-memory";
  throw MemoryLimitExceeded(message, stage, estimateBytes, budget);
}

}  // namespace duplexfit
