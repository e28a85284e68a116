// Bounded memory: the budget a command may commit to (ResourceLimits), its default from the machine, the
// byte-size parser of --max-memory, and the check every heavy stage makes with its estimate BEFORE it
// allocates (requireMemory). A refusal is a MemoryLimitExceeded, an InvalidArgument (the CLI's exit status
// 1, as the other limit refusals) whose message names the stage, the estimate, the budget and the options
// that change either.
#pragma once

#include <cstdint>
#include <string>

#include "duplexfit/error.hpp"

namespace duplexfit {

/// The memory a stage may plan to use. Estimates are of the stage's large arrays (grid nodes, matrices,
/// samples, pixels, contours), not of the whole process.
struct ResourceLimits {
  /// Bytes; 0: defaultMaxMemoryBytes() (a fraction of the machine's memory).
  std::uint64_t maxMemoryBytes = 0;
  /// The budget in bytes: maxMemoryBytes, or the default when it is 0.
  std::uint64_t bytes() const;
};

/// Physical memory of the machine (sysconf(_SC_PHYS_PAGES) · page size); 0 when unknown.
std::uint64_t physicalMemoryBytes();
/// The process's peak resident memory so far (getrusage: ru_maxrss); 0 when unknown.
std::uint64_t peakResidentBytes();
/// 75% of the physical memory, at most the address-space limit (RLIMIT_AS) when one is set; 8 GiB when the
/// physical memory is unknown.
std::uint64_t defaultMaxMemoryBytes();

/// "8G", "512M", "1.5GiB", "64k", "1000000" (bytes): a positive size. K, M, G, T (with or without "iB" or
/// "B", either case) are powers of 1024; a plain number is bytes. At least 1 MiB, at most 2^60 bytes.
/// @throws InvalidArgument naming `what` (e.g. "--max-memory") and the accepted forms.
std::uint64_t parseByteSize(const std::string& text, const std::string& what = "--max-memory");
/// "34.2 GiB", "512 MiB", "900 KiB", "12 bytes": three significant digits.
std::string formatBytes(double bytes);

/// A stage's estimate is over the budget.
class MemoryLimitExceeded : public InvalidArgument {
 public:
  MemoryLimitExceeded(const std::string& message, std::string stage, double estimate, std::uint64_t budget)
      : InvalidArgument(message), stage_(std::move(stage)), estimate_(estimate), budget_(budget) {}
  const std::string& stage() const noexcept { return stage_; }
  double estimate() const noexcept { return estimate_; }
  std::uint64_t budget() const noexcept { return budget_; }

 private:
  std::string stage_;
  double estimate_;
  std::uint64_t budget_;
};

/// Throws MemoryLimitExceeded when `estimateBytes` > limits.bytes():
///   "<stage>: <what> needs about <estimate>, more than --max-memory <budget>; <advice>, or raise --max-memory"
/// `what` names the work ("the 2049x2049x2049 grid (8.6e9 nodes) with 2 level sets"); `advice` the options
/// that shrink it ("use a larger --cell or a smaller --resolution").
void requireMemory(const ResourceLimits& limits, const std::string& stage, double estimateBytes, const std::string& what,
                   const std::string& advice);

}  // namespace duplexfit
