// Options, statistics, timing, the host STREAM triad and table printing of duplexfit-bench.
#include "harness.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>
#include <thread>

#include <unistd.h>

#include "duplexfit/error.hpp"

#ifndef DUPLEXFIT_GIT_DESCRIBE
#define DUPLEXFIT_GIT_DESCRIBE "unknown"
#endif
#ifndef DUPLEXFIT_BUILD_TYPE
#define DUPLEXFIT_BUILD_TYPE "unknown"
#endif
#ifndef DUPLEXFIT_COMPILER
#define DUPLEXFIT_COMPILER "unknown"
#endif
#ifndef DUPLEXFIT_CXX_FLAGS
#define DUPLEXFIT_CXX_FLAGS ""
#endif

namespace duplexfit::bench {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const char* const kUsage = R"(usage: duplexfit-bench [options]
SpMV and CG on OpenCL devices and the reference device, against Eigen and the STREAM triad.

  --device=SPEC         device to run on (repeatable; "ref", "0:0", "cpu", a name substring);
                        default: every OpenCL device and the reference device
  --sizes=LIST          system sizes in unknowns (3 per surface point), e.g. 150k,600k,3M (the default)
  --shape=sphere|torus  sampled shape (default sphere)
  --precision=LIST      float,double (default both)
  --trials=N            timed SpMV and kernel trials after one warm-up (default 10)
  --cg-trials=N         timed CG solves (default 5)
  --triad-trials=N      STREAM triad trials, best of N (default 10)
  --triad-elements=N    elements of each triad array (default 40M: 960 MB of doubles)
  --rhs=random|ones     CG right-hand side: b = A*(random vector) (default) or b = 1
  --filter=LIST         cases: triad, spmv, kernels, cg (repeatable; default all)
  --no-eigen            skip the Eigen SpMV and CG baselines (launch-parameter sweeps)
  --csv                 CSV instead of aligned tables
  --quick               smoke run: 15k unknowns, 1 trial, small triad (CI)
  --list                list the cases
  --help                this text
Progress goes to stderr, tables to stdout.
)";

const char* const kCases = R"(triad    STREAM triad a = b + s*c: host (OpenMP, double) and on each device (float and double)
spmv     y = A*x: row-per-item and row-per-group kernels, reference loop, Eigen; ms, GB/s, % of triad
kernels  the operations of one CG iteration timed apart (spmvDot, cgUpdate, cgDirection) vs traffic
cg       Jacobi-PCG from x = 0: iterations, ms, ms/iteration, residual; Eigen ConjugateGradient
)";

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

int parsePositive(const std::string& name, const std::string& value) {
  const long v = parseCount(value);
  if (v <= 0 || v > 1'000'000) throw InvalidArgument("--" + name + " must be a positive integer, got '" + value + "'");
  return static_cast<int>(v);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

}  // namespace

bool Options::runs(const std::string& name) const {
  return filters.empty() || std::find(filters.begin(), filters.end(), name) != filters.end();
}

long parseCount(const std::string& text) {
  if (text.empty()) throw InvalidArgument("empty count");
  std::size_t pos = 0;
  double v = 0.0;
  try {
    v = std::stod(text, &pos);
  } catch (const std::exception&) {
    throw InvalidArgument("not a count: '" + text + "'");
  }
  const std::string suffix = lower(text.substr(pos));
  if (suffix == "k") {
    v *= 1e3;
  } else if (suffix == "m") {
    v *= 1e6;
  } else if (!suffix.empty()) {
    throw InvalidArgument("not a count: '" + text + "' (suffixes: k, M)");
  }
  if (!(v >= 0.0) || v > 1e12) throw InvalidArgument("count out of range: '" + text + "'");
  return std::lround(v);
}

std::string countName(long n) {
  if (n >= 1'000'000 && n % 100'000 == 0) {
    std::ostringstream s;
    s << static_cast<double>(n) / 1e6 << "M";
    return s.str();
  }
  if (n >= 1000 && n % 100 == 0) {
    std::ostringstream s;
    s << static_cast<double>(n) / 1e3 << "k";
    return s.str();
  }
  return std::to_string(n);
}

Options parseOptions(int argc, char** argv) {
  Options o;
  bool sizesGiven = false, trialsGiven = false, cgTrialsGiven = false, triadTrialsGiven = false,
       triadElementsGiven = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto eq = arg.find('=');
    const std::string key = arg.substr(0, eq);
    const std::string value = eq == std::string::npos ? std::string() : arg.substr(eq + 1);
    auto need = [&]() {
      if (eq == std::string::npos || value.empty()) throw InvalidArgument(key + " needs a value (" + key + "=...)");
    };
    if (key == "--help" || key == "-h") {
      std::cout << kUsage;
      std::exit(0);
    } else if (key == "--list") {
      std::cout << kCases;
      std::exit(0);
    } else if (key == "--device") {
      need();
      o.deviceSpecs.push_back(value);
    } else if (key == "--sizes") {
      need();
      o.unknowns.clear();  // the last --sizes wins
      for (const std::string& s : splitList(value)) {
        const long n = parseCount(s);
        if (n < 3) throw InvalidArgument("--sizes: a system needs at least 3 unknowns, got '" + s + "'");
        o.unknowns.push_back(n);
      }
      sizesGiven = true;
    } else if (key == "--shape") {
      need();
      const std::string v = lower(value);
      if (v != "sphere" && v != "torus") throw InvalidArgument("--shape must be sphere or torus, got '" + value + "'");
      o.sphere = v == "sphere";
    } else if (key == "--precision") {
      need();
      o.precisions.clear();
      for (const std::string& s : splitList(value)) o.precisions.push_back(parsePrecision(s.c_str()));
    } else if (key == "--trials") {
      need();
      o.trials = parsePositive("trials", value);
      trialsGiven = true;
    } else if (key == "--cg-trials") {
      need();
      o.cgTrials = parsePositive("cg-trials", value);
      cgTrialsGiven = true;
    } else if (key == "--triad-trials") {
      need();
      o.triadTrials = parsePositive("triad-trials", value);
      triadTrialsGiven = true;
    } else if (key == "--triad-elements") {
      need();
      o.triadElements = parseCount(value);
      if (o.triadElements < 1000) throw InvalidArgument("--triad-elements must be at least 1000");
      triadElementsGiven = true;
    } else if (key == "--rhs") {
      need();
      const std::string v = lower(value);
      if (v != "random" && v != "ones") throw InvalidArgument("--rhs must be random or ones, got '" + value + "'");
      o.rhsOnes = v == "ones";
    } else if (key == "--filter") {
      need();
      for (const std::string& s : splitList(lower(value))) {
        if (s != "triad" && s != "spmv" && s != "kernels" && s != "cg") {
          throw InvalidArgument("--filter: unknown case '" + s + "' (triad, spmv, kernels, cg)");
        }
        o.filters.push_back(s);
      }
    } else if (key == "--no-eigen") {
      o.eigen = false;
    } else if (key == "--csv") {
      o.csv = true;
    } else if (key == "--quick") {
      o.quick = true;
    } else {
      throw InvalidArgument("unknown option '" + arg + "' (see --help)");
    }
  }
  if (o.precisions.empty()) o.precisions = {Precision::Float, Precision::Double};
  if (o.quick) {
    if (!sizesGiven) o.unknowns = {15'000};
    if (!trialsGiven) o.trials = 1;
    if (!cgTrialsGiven) o.cgTrials = 1;
    if (!triadTrialsGiven) o.triadTrials = 2;
    if (!triadElementsGiven) o.triadElements = 4'000'000;  // 96 MB of doubles: still beyond a 32 MB L3
  }
  if (o.unknowns.empty()) o.unknowns = {150'000, 600'000, 3'000'000};
  return o;
}

Stats Stats::of(std::vector<double> samples) {
  Stats s;
  s.count = static_cast<int>(samples.size());
  if (samples.empty()) {
    s.min = s.median = s.mean = s.stddev = kNaN;
    return s;
  }
  std::sort(samples.begin(), samples.end());
  const std::size_t n = samples.size();
  s.min = samples.front();
  s.median = n % 2 == 1 ? samples[n / 2] : 0.5 * (samples[n / 2 - 1] + samples[n / 2]);
  s.mean = std::accumulate(samples.begin(), samples.end(), 0.0) / static_cast<double>(n);
  double ss = 0.0;
  for (double v : samples) ss += (v - s.mean) * (v - s.mean);
  s.stddev = n > 1 ? std::sqrt(ss / static_cast<double>(n - 1)) : 0.0;
  return s;
}

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  if (!(in >> a >> b >> c)) return "?";
  return a + " " + b + " " + c;
}

namespace {

// Busy CPU seconds of the whole machine (all CPUs) and of this process, from procfs.
double machineBusySeconds() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  double user = 0, nice = 0, system = 0, idle = 0, iowait = 0, irq = 0, softirq = 0, steal = 0;
  if (!(in >> cpu >> user >> nice >> system >> idle >> iowait >> irq >> softirq >> steal)) return 0.0;
  return (user + nice + system + irq + softirq + steal) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

double ownBusySeconds() {
  std::ifstream in("/proc/self/stat");
  std::string all;
  std::getline(in, all);
  // Fields after the command name, which is in parentheses and may hold spaces.
  const auto close = all.rfind(')');
  if (close == std::string::npos) return 0.0;
  std::istringstream rest(all.substr(close + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  return (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

}  // namespace

ForeignLoad::ForeignLoad() : wall0_(nowSeconds()), busy0_(machineBusySeconds()), own0_(ownBusySeconds()) {}

double ForeignLoad::cpuSeconds() const {
  return std::max(0.0, (machineBusySeconds() - busy0_) - (ownBusySeconds() - own0_));
}

double ForeignLoad::share() const {
  const double wall = nowSeconds() - wall0_;
  const double cpus = static_cast<double>(std::max(1u, std::thread::hardware_concurrency()));
  return wall > 0.0 ? cpuSeconds() / (wall * cpus) : 0.0;
}

std::string ForeignLoad::describe() const {
  return "other processes used " + fmt(cpuSeconds(), 1) + " CPU-s in " + fmt(nowSeconds() - wall0_, 1) + " s (" +
         pct(share()) + " of the machine)";
}

TriadResult hostTriad(std::size_t n, int trials) {
  // Raw arrays, first touched in parallel with the same static schedule as the triad.
  std::unique_ptr<double[]> a(new double[n]), b(new double[n]), c(new double[n]);
  const auto count = static_cast<std::ptrdiff_t>(n);
  double* pa = a.get();
  double* pb = b.get();
  double* pc = c.get();
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < count; ++i) {
    pa[i] = 0.0;
    pb[i] = 1.0;
    pc[i] = 2.0;
  }
  const double s = 3.0;
  std::vector<double> ms;
  for (int t = 0; t <= trials; ++t) {
    const double t0 = nowSeconds();
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t i = 0; i < count; ++i) pa[i] = pb[i] + s * pc[i];
    const double dt = (nowSeconds() - t0) * 1e3;
    if (t > 0) ms.push_back(dt);  // the first pass is a warm-up
  }
  // Keep the result observable so the loops cannot be dropped.
  if (pa[count / 2] != 7.0) std::cerr << "host triad: unexpected value " << pa[count / 2] << "\n";
  const Stats st = Stats::of(ms);
  TriadResult r;
  r.elements = n;
  r.bytesPerElement = 3 * sizeof(double);
  const double bytes = static_cast<double>(n) * static_cast<double>(r.bytesPerElement);
  r.bestMs = st.min;
  r.medianMs = st.median;
  r.bestGBs = bytes / (st.min * 1e-3) * 1e-9;
  r.medianGBs = bytes / (st.median * 1e-3) * 1e-9;
  return r;
}

BuildInfo BuildInfo::current() {
  BuildInfo b;
  b.buildType = DUPLEXFIT_BUILD_TYPE;
  b.compiler = DUPLEXFIT_COMPILER;
  b.flags = DUPLEXFIT_CXX_FLAGS;
  b.flags.erase(0, b.flags.find_first_not_of(' '));
  b.flags.erase(b.flags.find_last_not_of(' ') + 1);
  b.git = DUPLEXFIT_GIT_DESCRIBE;
#ifndef NDEBUG
  b.buildType += " (assertions on)";
#endif
  b.threads = omp_get_max_threads();
  b.cores = static_cast<int>(std::thread::hardware_concurrency());
  std::ifstream cpuinfo("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpuinfo, line)) {
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) b.cpu = line.substr(line.find_first_not_of(" \t", colon + 1));
      break;
    }
  }
  if (b.cpu.empty()) b.cpu = "unknown CPU";
  return b;
}

std::string BuildInfo::describe() const {
  std::ostringstream s;
  s << "build: " << buildType << " | compiler: " << compiler;
  if (!flags.empty()) s << " " << flags;
  s << " | git: " << git << " | host: " << cpu << ", " << cores << " hardware threads, OpenMP " << threads
    << " threads";
  return s.str();
}

DeviceLabel DeviceLabel::of(const Device& device) {
  DeviceLabel l;
  const DeviceInfo& info = device.info();
  l.spec = info.spec;
  if (device.isReference()) {
    l.name = "reference (C++ loops, OpenMP " + std::to_string(omp_get_max_threads()) + " threads)";
    l.platform = "host";
    l.driver = "-";
    l.params = "-";
  } else {
    l.name = info.name;
    l.platform = info.platform;
    l.driver = info.driverVersion;
    l.params = device.tuning().describe();
  }
  const auto gib = [](std::uint64_t bytes) { return fmt(static_cast<double>(bytes) / double(1ull << 30), 1); };
  l.memory = gib(info.globalMemBytes) + " GiB, buffers <= " + gib(device.maxAllocBytes()) + " GiB";
  return l;
}

Table::Table(std::string title, std::vector<std::string> columns)
    : title_(std::move(title)), columns_(std::move(columns)) {}

void Table::addRow(std::vector<std::string> cells) {
  cells.resize(columns_.size());
  rows_.push_back(std::move(cells));
}

namespace {

std::string csvCell(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char c : s) {
    if (c == '"') out += '"';
    out += c;
  }
  return out + "\"";
}

// Display width of UTF-8 text (continuation bytes do not count).
std::size_t width(const std::string& s) {
  std::size_t w = 0;
  for (unsigned char c : s) w += (c & 0xC0) != 0x80 ? 1 : 0;
  return w;
}

}  // namespace

void Table::print(std::ostream& out, bool csv,
                  const std::vector<std::pair<std::string, std::string>>& context) const {
  if (csv) {
    out << "# " << title_ << "\n";
    bool first = true;
    for (const auto& kv : context) {
      out << (first ? "" : ",") << csvCell(kv.first);
      first = false;
    }
    for (const std::string& c : columns_) {
      out << (first ? "" : ",") << csvCell(c);
      first = false;
    }
    out << "\n";
    for (const auto& row : rows_) {
      first = true;
      for (const auto& kv : context) {
        out << (first ? "" : ",") << csvCell(kv.second);
        first = false;
      }
      for (const std::string& c : row) {
        out << (first ? "" : ",") << csvCell(c);
        first = false;
      }
      out << "\n";
    }
    out << "\n";
    return;
  }
  std::vector<std::size_t> w(columns_.size());
  for (std::size_t j = 0; j < columns_.size(); ++j) {
    w[j] = width(columns_[j]);
    for (const auto& row : rows_) w[j] = std::max(w[j], width(row[j]));
  }
  auto line = [&](const std::vector<std::string>& cells) {
    std::string s;
    for (std::size_t j = 0; j < cells.size(); ++j) {
      const std::string pad(w[j] - width(cells[j]), ' ');
      if (j > 0) s += "  ";
      s += j < left_ ? cells[j] + pad : pad + cells[j];
    }
    while (!s.empty() && s.back() == ' ') s.pop_back();
    out << s << "\n";
  };
  out << title_ << "\n";
  line(columns_);
  for (const auto& row : rows_) line(row);
  out << "\n";
}

std::string fmt(double value, int digits) {
  if (std::isnan(value)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << value;
  return s.str();
}

std::string sci(double value) {
  if (std::isnan(value)) return "-";
  std::ostringstream s;
  s << std::scientific << std::setprecision(1) << value;
  return s.str();
}

std::string pct(double fraction) {
  if (std::isnan(fraction)) return "-";
  std::ostringstream s;
  s << std::fixed << std::setprecision(0) << fraction * 100.0 << "%";
  return s.str();
}

std::string human(double count) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(1);
  if (count >= 1e6) {
    s << count / 1e6 << "M";
  } else if (count >= 1e3) {
    s << count / 1e3 << "k";
  } else {
    s << std::setprecision(0) << count;
  }
  return s.str();
}

}  // namespace duplexfit::bench
