// The hand-rolled benchmark harness of duplexfit-bench (docs/style.md §9): command-line options, trial
// statistics, wall and device (event) timing of queued work, the host STREAM triad, and aligned-text or
// CSV tables with the build/device header that every table carries.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::bench {

/// What to run, from the command line.
struct Options {
  std::vector<std::string> deviceSpecs;  ///< --device=SPEC (repeatable); empty: every device and "ref"
  std::vector<long> unknowns;            ///< --sizes=150k,600k,3M: rows of each system (3 per surface point)
  bool sphere = true;                    ///< --shape=sphere|torus
  std::vector<Precision> precisions;     ///< --precision=float,double
  int trials = 10;                       ///< --trials=N: timed SpMV / kernel trials
  int cgTrials = 5;                      ///< --cg-trials=N: timed CG solves (each a full solve)
  int triadTrials = 10;                  ///< --triad-trials=N
  long triadElements = 40'000'000;       ///< --triad-elements=N: elements of each triad array
  bool rhsOnes = false;                  ///< --rhs=ones|random: b = 1 or b = A·(random vector)
  bool eigen = true;                     ///< --no-eigen skips the Eigen baselines
  bool csv = false;                      ///< --csv
  bool quick = false;                    ///< --quick: CI smoke run
  std::vector<std::string> filters;      ///< --filter=triad|spmv|kernels|cg (repeatable, comma lists)

  /// Whether a case runs (no filter: every case).
  bool runs(const std::string& name) const;
};

/// Parses argv. Prints usage and exits on --help or --list; throws InvalidArgument on bad options.
Options parseOptions(int argc, char** argv);

/// "150k" → 150000, "3M" → 3000000, "15000" → 15000. @throws InvalidArgument.
long parseCount(const std::string& text);
/// 150000 → "150k", 3000000 → "3M" (for system names).
std::string countName(long n);

/// min / median / mean / sample standard deviation of a set of trials.
struct Stats {
  double min = 0.0, median = 0.0, mean = 0.0, stddev = 0.0;
  int count = 0;
  static Stats of(std::vector<double> samples);
};

/// Times queued work on a device (wall and profiled device time): the library's DeviceStopwatch.
using Stopwatch = DeviceStopwatch;

/// Wall and device trials of one operation.
struct Timing {
  Stats wall;    ///< ms
  Stats device;  ///< ms (all NaN on the reference device)
};

/// Runs op() once untimed (warm-up: program builds, first launch at this size), then `trials` times
/// between Stopwatch start/stop.
template <typename Op>
Timing timeTrials(const Device& device, int trials, Op&& op) {
  op();
  device.finish();
  std::vector<double> wall, dev;
  Stopwatch sw(device);
  for (int t = 0; t < trials; ++t) {
    sw.start();
    op();
    sw.stop();
    wall.push_back(sw.wallMs());
    dev.push_back(sw.deviceMs());
  }
  return {Stats::of(wall), Stats::of(dev)};
}

/// Seconds on a monotonic clock.
double nowSeconds();

/// The first three fields of /proc/loadavg ("1.02 0.80 0.55"), or "?": other work skews timings.
std::string loadAverage();

/// CPU time other processes used since construction (from /proc/stat minus this process's own time,
/// /proc/self/stat): on a shared machine, the figure that says whether a timing can be trusted.
class ForeignLoad {
 public:
  ForeignLoad();
  /// Seconds of CPU other processes used since construction, and that as a share of all CPUs' time.
  double cpuSeconds() const;
  double share() const;
  std::string describe() const;

 private:
  double wall0_ = 0.0, busy0_ = 0.0, own0_ = 0.0;
};

/// Best and median GB/s of the STREAM triad a = b + s·c over three arrays of n doubles on the host,
/// OpenMP over all threads, counting 24 bytes an element as STREAM does.
struct TriadResult {
  double bestGBs = 0.0, medianGBs = 0.0, bestMs = 0.0, medianMs = 0.0;
  std::size_t elements = 0;
  std::size_t bytesPerElement = 0;
};
TriadResult hostTriad(std::size_t n, int trials);

/// The build: type, compiler, flags, git describe, OpenMP threads, host CPU.
struct BuildInfo {
  std::string buildType, compiler, flags, git, cpu;
  int threads = 1;
  int cores = 1;
  static BuildInfo current();
  std::string describe() const;
};

/// What a table header names about a device.
struct DeviceLabel {
  std::string spec, name, platform, driver, params;
  std::string memory;  ///< global memory and largest buffer, e.g. "17.0 GiB, buffers <= 4.3 GiB"
  static DeviceLabel of(const Device& device);
};

/// A table printed as aligned text or CSV. Context columns (device, precision, build, …) are printed in
/// CSV rows only; in text they belong to the header printed above the table.
class Table {
 public:
  Table(std::string title, std::vector<std::string> columns);
  /// Columns [0, n) are left-aligned (names); the rest right-aligned (numbers).
  void setLeftColumns(std::size_t n) { left_ = n; }
  void addRow(std::vector<std::string> cells);
  bool empty() const { return rows_.empty(); }
  /// Text: the title and the aligned table. CSV: "# title", a header row, rows (context columns first).
  void print(std::ostream& out, bool csv, const std::vector<std::pair<std::string, std::string>>& context) const;

 private:
  std::string title_;
  std::vector<std::string> columns_;
  std::vector<std::vector<std::string>> rows_;
  std::size_t left_ = 1;
};

/// Fixed-point number with `digits` decimals; "-" for NaN.
std::string fmt(double value, int digits = 2);
/// Scientific notation with 2 significant decimals ("1.2e-07"); "-" for NaN.
std::string sci(double value);
/// Percentage with no decimals ("78%"); "-" for NaN.
std::string pct(double fraction);
/// 138123456 → "138.1M", 45000 → "45.0k".
std::string human(double count);

}  // namespace duplexfit::bench
