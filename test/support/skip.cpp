// The skip tally of a test run (skip.hpp).
#include "skip.hpp"

#include <algorithm>

namespace duplexfit::testing {

namespace {

struct State {
  SkipTally tally;
  std::string current;       ///< the running test case ("" between cases)
  bool currentSkipped = false;
};

State& state() {
  static State s;
  return s;
}

}  // namespace

void testCaseStarted(const std::string& name) {
  State& s = state();
  ++s.tally.ran;
  s.current = name;
  s.currentSkipped = false;
}

void testCaseEnded() {
  State& s = state();
  if (s.currentSkipped) ++s.tally.skipped;
  s.current.clear();
  s.currentSkipped = false;
}

void skipTestCase(const std::string& reason) {
  State& s = state();
  // A case re-entered for its subcases may skip again: record it once.
  if (s.currentSkipped) return;
  s.currentSkipped = true;
  s.tally.entries.push_back({s.current, reason, true});
}

void skipPart(const std::string& reason) {
  State& s = state();
  const bool known = std::any_of(s.tally.entries.begin(), s.tally.entries.end(), [&](const SkipEntry& e) {
    return !e.whole && e.testCase == s.current && e.reason == reason;
  });
  if (!known) s.tally.entries.push_back({s.current, reason, false});
}

const SkipTally& skipTally() { return state().tally; }

std::string skipSummary() {
  const SkipTally& t = skipTally();
  if (t.entries.empty()) return {};
  std::ostringstream out;
  const auto parts = static_cast<unsigned>(
      std::count_if(t.entries.begin(), t.entries.end(), [](const SkipEntry& e) { return !e.whole; }));
  out << "[duplexfit tests] " << t.ran << " test case(s) ran, " << t.skipped << " of them skipped";
  if (parts > 0) out << ", " << parts << " part(s) skipped";
  out << ":\n";
  for (const SkipEntry& e : t.entries) {
    out << (e.whole ? "  SKIPPED: " : "  SKIPPED (part): ") << e.testCase << ": " << e.reason << "\n";
  }
  return out.str();
}

}  // namespace duplexfit::testing
