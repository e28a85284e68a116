// duplexfit-bench: SpMV and Jacobi-PCG on every OpenCL device and the reference device for Wendland
// systems of a sampled sphere or torus (3 centres a surface point), against Eigen on the CPU and against
// the machine's own STREAM triad bandwidth (docs/benchmarks.md, docs/style.md §9).
#include <omp.h>

#include <Eigen/Core>

#include <cmath>
#include <exception>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/wendland.hpp"
#include "eigen_baseline.hpp"
#include "harness.hpp"
#include "duplexfit/cg_steps.hpp"
#include "shapes.hpp"

namespace duplexfit::bench {

namespace {

constexpr double kDelta = 0.05;       // inward offset of the second centre layer (sphere radius 0.5)
constexpr double kNonZeros = 45.0;    // wanted mean non-zeros a row
constexpr int kMaxIterations = 20000; // SolverOptions' default cap, also given to Eigen

double realBytes(Precision p) { return p == Precision::Double ? 8.0 : 4.0; }

double defaultTolerance(Precision p) { return p == Precision::Double ? 1e-6 : 1e-5; }

double startTime = nowSeconds();

/// A progress line on stderr, stamped with seconds since start.
void progress(const std::string& text) {
  std::ostringstream s;
  s << "[" << fmt(nowSeconds() - startTime, 1) << " s] " << text << "\n";
  std::cerr << s.str() << std::flush;
}

struct System {
  std::string name;  ///< e.g. "sphere-600k"
  int surfacePoints = 0;
  double sigma = 0.0;
  double assemblySeconds = 0.0;
  CsrMatrix a;
  Eigen::VectorXd x;  ///< random in [−1, 1] (fixed seed)
  Eigen::VectorXd y;  ///< A·x on the host in double
  Eigen::VectorXd b;  ///< CG right-hand side: A·x or ones
  Index minRow = 0, maxRow = 0;
};

System buildSystem(bool sphere, long unknowns, bool rhsOnes) {
  const auto shape = sphere ? testing::Shape::Sphere : testing::Shape::Torus;
  System s;
  s.surfacePoints = static_cast<int>((unknowns + 1) / 3);
  s.name = std::string(sphere ? "sphere" : "torus") + "-" + countName(unknowns);
  progress("building " + s.name + ": " + std::to_string(s.surfacePoints) + " surface points, " +
           std::to_string(3L * s.surfacePoints) + " unknowns");
  double t0 = nowSeconds();
  s.sigma = testing::sigmaForNonZeros(shape, s.surfacePoints, kDelta, kNonZeros);
  const testing::LevelCentres level = testing::levelCentres(shape, s.surfacePoints, kDelta, s.sigma);
  progress("  sigma " + sci(s.sigma) + ", centres in " + fmt(nowSeconds() - t0, 2) + " s; assembling");
  t0 = nowSeconds();
  s.a = assembleWendland(level.centres, s.sigma);
  s.assemblySeconds = nowSeconds() - t0;
  s.minRow = s.a.rows > 0 ? s.a.rowPtr[1] - s.a.rowPtr[0] : 0;
  for (Index i = 0; i < s.a.rows; ++i) {
    const Index len = s.a.rowPtr[static_cast<std::size_t>(i) + 1] - s.a.rowPtr[static_cast<std::size_t>(i)];
    s.minRow = std::min(s.minRow, len);
    s.maxRow = std::max(s.maxRow, len);
  }
  const double perRow = static_cast<double>(s.a.nonZeros()) / static_cast<double>(s.a.rows);
  progress("  assembly " + fmt(s.assemblySeconds, 2) + " s: " + std::to_string(s.a.rows) + " rows, " +
           human(static_cast<double>(s.a.nonZeros())) + " non-zeros (" + fmt(perRow, 1) + " a row, min " +
           std::to_string(s.minRow) + ", max " + std::to_string(s.maxRow) + ")");
  if (perRow < 30.0 || perRow > 60.0) progress("  warning: mean row length outside 30-60");

  std::mt19937_64 engine(20240611);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  s.x.resize(s.a.cols);
  for (Eigen::Index i = 0; i < s.x.size(); ++i) s.x[i] = uniform(engine);
  s.y = s.a.multiply(s.x);
  s.b = rhsOnes ? Eigen::VectorXd::Ones(s.a.rows) : s.y;
  return s;
}

/// Bytes of one SpMV as DeviceCsr::spmvBytes() counts them (for Eigen, which has no DeviceCsr).
double spmvBytes(const CsrMatrix& a, Precision p) {
  const double real = realBytes(p);
  return static_cast<double>(a.nonZeros()) * (real + sizeof(Index)) + static_cast<double>(a.rows + 1) * sizeof(Index) +
         static_cast<double>(a.cols) * real + static_cast<double>(a.rows) * real;
}

/// Bytes of one fused CG iteration: SpMV + p·q, then cgUpdate (reads p, q, D⁻¹, x, r; writes x, r) and
/// cgDirection (reads r, D⁻¹, p; writes p): 11 vector passes besides the SpMV.
double iterationBytes(const CsrMatrix& a, Precision p) {
  return spmvBytes(a, p) + 11.0 * static_cast<double>(a.rows) * realBytes(p);
}

double gbs(double bytes, double ms) { return std::isnan(ms) || ms <= 0.0 ? std::nan("") : bytes / (ms * 1e6); }

double maxRelError(const Eigen::VectorXd& y, const Eigen::VectorXd& ref) {
  const double scale = ref.cwiseAbs().maxCoeff();
  return (y - ref).cwiseAbs().maxCoeff() / (scale > 0.0 ? scale : 1.0);
}

/// Everything printed under one device × precision header.
struct Block {
  Device device;
  DeviceLabel label;
  Precision precision;
  TriadResult triad;  ///< this device's triad in this precision (elements = 0 when not measured)
  Table spmv{"SpMV y = A*x (GB/s from the min; %host triad: of the host triad measured just before the system; "
             "%dev triad: of this device's triad at start)",
             {"system", "kernel", "med ms", "min ms", "dev ms", "GB/s", "GB/s med", "%host triad", "%dev triad",
              "rel err", "Eigen ms", "Eigen GB/s", "Eigen %host triad", "Eigen/ours"}};
  Table kernels{"CG iteration, operations timed apart in solver order (MB: minimum traffic; floor: MB at this "
                "device's triad)",
                {"system", "operation", "MB", "med ms", "min ms", "dev ms", "GB/s", "%dev triad", "floor ms"}};
  Table cg{"CG from x = 0 (Jacobi), relative tolerance as below; ms/it = total / iterations; floor = iteration "
           "bytes at the host triad measured just before the system",
           {"system", "solver", "iters", "med ms", "min ms", "ms/it", "min ms/it", "floor ms/it", "rel res", "tol",
            "status", "ours/Eigen (med)", "ours/Eigen (min)"}};
  std::vector<std::string> notes;

  Block(const Device& d, Precision p) : device(d), label(DeviceLabel::of(d)), precision(p) {
    spmv.setLeftColumns(2);
    kernels.setLeftColumns(2);
    cg.setLeftColumns(2);
  }
};

struct EigenResults {
  bool haveSpmv = false, haveCg = false;
  EigenSpmvResult spmv{};
  EigenCgResult cg;
};

TriadResult deviceTriad(const Device& device, Precision p, std::size_t n, int trials) {
  DeviceVector a(device, n, p), b(device, n, p), c(device, n, p);
  b.fill(1.0);
  c.fill(2.0);
  const Timing t = timeTrials(device, trials, [&] { steps::triad(a, b, c, 3.0); });
  TriadResult r;
  r.elements = n;
  r.bytesPerElement = 3 * static_cast<std::size_t>(realBytes(p));
  const double bytes = static_cast<double>(n) * static_cast<double>(r.bytesPerElement);
  r.bestMs = t.wall.min;
  r.medianMs = t.wall.median;
  r.bestGBs = gbs(bytes, t.wall.min);
  r.medianGBs = gbs(bytes, t.wall.median);
  return r;
}

void runSpmv(Block& blk, const System& sys, const DeviceCsr& a, const EigenResults& eig, const TriadResult& host,
             int trials) {
  const Device& device = blk.device;
  const DeviceVector x = DeviceVector::upload(device, sys.x, blk.precision);
  DeviceVector y(device, a.rows(), blk.precision);
  const double bytes = a.spmvBytes();
  std::vector<std::pair<SpmvKernel, const char*>> kernels;
  if (device.isReference()) {
    kernels = {{SpmvKernel::Auto, "reference"}};
  } else {
    kernels = {{SpmvKernel::RowPerItem, "row-per-item"}, {SpmvKernel::RowPerGroup, "row-per-group"}};
  }
  for (const auto& [kernel, name] : kernels) {
    const Timing t = timeTrials(device, trials, [&, k = kernel] { spmv(a, x, y, k); });
    const double err = maxRelError(y.download(), sys.y);
    const double best = gbs(bytes, t.wall.min);
    const double eigenBest = eig.haveSpmv ? gbs(spmvBytes(sys.a, blk.precision), eig.spmv.ms.min) : std::nan("");
    blk.spmv.addRow({sys.name, name, fmt(t.wall.median, 3), fmt(t.wall.min, 3), fmt(t.device.median, 3), fmt(best, 1),
                     fmt(gbs(bytes, t.wall.median), 1), pct(best / host.bestGBs), pct(best / blk.triad.bestGBs),
                     sci(err), eig.haveSpmv ? fmt(eig.spmv.ms.median, 3) : "-", fmt(eigenBest, 1),
                     pct(eigenBest / host.bestGBs), eig.haveSpmv ? fmt(eig.spmv.ms.median / t.wall.median, 2) : "-"});
    progress("  spmv " + std::string(name) + ": median " + fmt(t.wall.median, 3) + " ms, min " + fmt(t.wall.min, 3) +
             " ms, " + fmt(best, 1) + " GB/s = " + pct(best / host.bestGBs) + " of host triad, " +
             pct(best / blk.triad.bestGBs) + " of device triad; rel err " + sci(err));
  }
}

void runKernels(Block& blk, const System& sys, const DeviceCsr& a, int trials) {
  const Device& device = blk.device;
  const Precision prec = blk.precision;
  const std::size_t n = a.rows();
  const double vec = static_cast<double>(n) * realBytes(prec);
  DeviceVector p = DeviceVector::upload(device, sys.x, prec);
  DeviceVector r = DeviceVector::upload(device, sys.y, prec);
  DeviceVector q(device, n, prec), x(device, n, prec);
  const DeviceVector dinv = DeviceVector::upload(device, a.diagonal().cwiseInverse(), prec);
  const SpmvKernel kernel = steps::resolveSpmvKernel(device, SpmvKernel::Auto);
  auto row = [&](const std::string& op, double bytes, const Timing& t) {
    const double best = gbs(bytes, t.wall.min);
    blk.kernels.addRow({sys.name, op, fmt(bytes / 1e6, 1), fmt(t.wall.median, 3), fmt(t.wall.min, 3),
                        fmt(t.device.median, 3), fmt(best, 1), pct(best / blk.triad.bestGBs),
                        fmt(bytes / (blk.triad.bestGBs * 1e6), 3)});
    progress("  " + op + ": median " + fmt(t.wall.median, 3) + " ms (" + fmt(best, 1) + " GB/s best)");
  };
  // One iteration of the fused solver, in solver order so that each operation finds the caches as it
  // does inside solveCg: q = A p with p·q; x, r update with r·z and r·r; p = D r + β p. Each operation
  // is timed on its own (finish before and after); one untimed iteration first.
  const char* names[3] = {"spmvDot", "cgUpdate", "cgDirection"};
  const double bytes[3] = {a.spmvBytes(), 7.0 * vec, 4.0 * vec};
  auto op = [&](int i) {
    if (i == 0) {
      (void)steps::spmvDot(a, p, q, kernel);
    } else if (i == 1) {
      (void)steps::cgUpdate(1e-3, p, q, dinv, x, r);
    } else {
      steps::cgDirection(0.5, r, dinv, p);
    }
  };
  for (int i = 0; i < 3; ++i) op(i);
  device.finish();
  std::vector<double> wall[4], dev[4];
  Stopwatch sw(device);
  for (int t = 0; t < trials; ++t) {
    double w = 0.0, d = 0.0;
    for (int i = 0; i < 3; ++i) {
      sw.start();
      op(i);
      sw.stop();
      wall[i].push_back(sw.wallMs());
      dev[i].push_back(sw.deviceMs());
      w += sw.wallMs();
      d += sw.deviceMs();
    }
    wall[3].push_back(w);
    dev[3].push_back(d);
  }
  for (int i = 0; i < 3; ++i) row(names[i], bytes[i], {Stats::of(wall[i]), Stats::of(dev[i])});
  row("sum: one iteration", bytes[0] + bytes[1] + bytes[2], {Stats::of(wall[3]), Stats::of(dev[3])});
  // For comparison, unfused operations, each repeated on its own (vectors below L3 size stay cached).
  row("spmv (repeated)", a.spmvBytes(), timeTrials(device, trials, [&] { spmv(a, p, q, kernel); }));
  row("dot (repeated)", 2.0 * vec, timeTrials(device, trials, [&] { (void)dot(r, q); }));
  row("axpy (repeated)", 3.0 * vec, timeTrials(device, trials, [&] { axpy(1e-3, q, x); }));
}

void runCg(Block& blk, const System& sys, const DeviceCsr& a, const EigenResults& eig, const TriadResult& host,
           int trials) {
  const Device& device = blk.device;
  const Precision prec = blk.precision;
  const DeviceVector b = DeviceVector::upload(device, sys.b, prec);
  DeviceVector x(device, a.rows(), prec);
  SolverOptions options;
  options.maxIterations = kMaxIterations;
  {
    SolverOptions warm = options;  // builds the blas1 and cg programs, first launches at this size
    warm.maxIterations = 1;
    (void)solveCg(a, b, x, warm);
  }
  std::vector<double> ms;
  SolveStats stats;
  for (int t = 0; t < trials; ++t) {
    x.fill(0.0);
    device.finish();
    const double t0 = nowSeconds();
    stats = solveCg(a, b, x, options);
    device.finish();
    ms.push_back((nowSeconds() - t0) * 1e3);
  }
  const Stats st = Stats::of(ms);
  const double relres = (sys.b - sys.a.multiply(x.download())).norm() / sys.b.norm();
  const double perIt = stats.iterations > 0 ? st.median / stats.iterations : std::nan("");
  const double floorMs = iterationBytes(sys.a, prec) / (host.bestGBs * 1e6);
  const double minPerIt = stats.iterations > 0 ? st.min / stats.iterations : std::nan("");
  double ratio = std::nan(""), ratioMin = std::nan("");
  if (eig.haveCg && eig.cg.iterations > 0) {
    ratio = perIt / (eig.cg.ms.median / eig.cg.iterations);
    ratioMin = minPerIt / (eig.cg.ms.min / eig.cg.iterations);
  }
  blk.cg.addRow({sys.name, "duplexfit", std::to_string(stats.iterations), fmt(st.median, 1), fmt(st.min, 1),
                 fmt(perIt, 2), fmt(minPerIt, 2), fmt(floorMs, 2), sci(relres), sci(stats.tolerance),
                 stopReasonName(stats.reason), fmt(ratio, 2), fmt(ratioMin, 2)});
  if (eig.haveCg) {
    const int its = std::max(1, eig.cg.iterations);
    blk.cg.addRow({sys.name, "Eigen CG", std::to_string(eig.cg.iterations), fmt(eig.cg.ms.median, 1),
                   fmt(eig.cg.ms.min, 1), fmt(eig.cg.ms.median / its, 2), fmt(eig.cg.ms.min / its, 2), fmt(floorMs, 2),
                   sci(eig.cg.relativeResidual), sci(defaultTolerance(prec)), eig.cg.status, "1.00", "1.00"});
  }
  if (std::abs(stats.tolerance - defaultTolerance(prec)) > 1e-15) {
    blk.notes.push_back("solveCg used tolerance " + sci(stats.tolerance) + ", Eigen " + sci(defaultTolerance(prec)));
  }
  progress("  cg: " + std::to_string(stats.iterations) + " iterations, median " + fmt(st.median, 1) + " ms (" +
           fmt(perIt, 2) + " ms/it), rel res " + sci(relres) + ", " + stopReasonName(stats.reason) +
           (eig.haveCg ? ", ours/Eigen per it " + fmt(ratio, 2) : ""));
}

std::vector<Device> openDevices(const Options& o) {
  std::vector<Device> devices;
  if (o.deviceSpecs.empty()) {
    for (const DeviceInfo& info : Device::enumerate()) devices.push_back(Device::open(info.spec));
    devices.push_back(Device::reference());
  } else {
    for (const std::string& spec : o.deviceSpecs) devices.push_back(Device::open(spec));
  }
  return devices;
}

std::string headerLine(const Block& blk, const BuildInfo& build) {
  std::ostringstream s;
  s << "== device " << blk.label.spec << ": " << blk.label.name << " | platform: " << blk.label.platform
    << " | driver: " << blk.label.driver << " | memory: " << blk.label.memory << " | launch: " << blk.label.params
    << " | precision: " << precisionName(blk.precision) << "\n   " << build.describe();
  return s.str();
}

int run(const Options& o) {
  const BuildInfo build = BuildInfo::current();
  Eigen::setNbThreads(omp_get_max_threads());
  progress(build.describe());
  const ForeignLoad foreign;
  const std::string loadBefore = loadAverage();
  progress("load average " + loadBefore);
  const std::vector<Device> devices = openDevices(o);
  for (const Device& d : devices) {
    progress("device " + d.info().spec + ": " + d.description() +
             (d.isReference() ? "" : " [" + DeviceLabel::of(d).params + "]"));
  }

  std::vector<Block> blocks;
  for (const Device& d : devices) {
    for (Precision p : o.precisions) blocks.emplace_back(d, p);
  }
  auto blockOf = [&](std::size_t di, std::size_t pi) -> Block& { return blocks[di * o.precisions.size() + pi]; };

  // STREAM triad: the host (double) and every device in every precision.
  TriadResult host;
  host.bestGBs = host.medianGBs = std::nan("");
  Table triad("STREAM triad a = b + s*c (best and median of N after a warm-up; 3 arrays, bytes counted as STREAM)",
              {"where", "precision", "elements", "MB", "best ms", "med ms", "best GB/s", "med GB/s"});
  triad.setLeftColumns(2);
  const bool needTriad = o.runs("triad") || o.runs("spmv") || o.runs("kernels") || o.runs("cg");
  if (needTriad) {
    progress("host triad: " + human(static_cast<double>(o.triadElements)) + " doubles an array, " +
             std::to_string(o.triadTrials) + " trials");
    host = hostTriad(static_cast<std::size_t>(o.triadElements), o.triadTrials);
    triad.addRow({"host (OpenMP " + std::to_string(build.threads) + " threads)", "double",
                  human(static_cast<double>(host.elements)),
                  fmt(static_cast<double>(host.elements * host.bytesPerElement) / 1e6, 0), fmt(host.bestMs, 2),
                  fmt(host.medianMs, 2), fmt(host.bestGBs, 1), fmt(host.medianGBs, 1)});
    progress("  host triad best " + fmt(host.bestGBs, 1) + " GB/s, median " + fmt(host.medianGBs, 1) + " GB/s");
    for (Block& blk : blocks) {
      if (blk.precision == Precision::Double && !blk.device.supportsDouble()) continue;
      try {
        blk.triad = deviceTriad(blk.device, blk.precision, static_cast<std::size_t>(o.triadElements), o.triadTrials);
        triad.addRow({"device " + blk.label.spec, precisionName(blk.precision),
                      human(static_cast<double>(blk.triad.elements)),
                      fmt(static_cast<double>(blk.triad.elements * blk.triad.bytesPerElement) / 1e6, 0),
                      fmt(blk.triad.bestMs, 2), fmt(blk.triad.medianMs, 2), fmt(blk.triad.bestGBs, 1),
                      fmt(blk.triad.medianGBs, 1)});
        progress("  device " + blk.label.spec + " " + precisionName(blk.precision) + " triad best " +
                 fmt(blk.triad.bestGBs, 1) + " GB/s");
      } catch (const std::exception& e) {
        blk.notes.push_back(std::string("triad failed: ") + e.what());
        progress("  device " + blk.label.spec + " triad failed: " + e.what());
      }
    }
  }
  for (Block& blk : blocks) {
    if (blk.triad.elements == 0) blk.triad.bestGBs = blk.triad.medianGBs = std::nan("");
  }

  Table systems("Systems (Wendland, delta = 0.05, sigma for ~45 non-zeros a row; 3 centres a surface point)",
                {"system", "surface pts", "rows", "nnz", "nnz/row", "min", "max", "sigma", "assembly s"});
  const bool anySystemCase = o.runs("spmv") || o.runs("kernels") || o.runs("cg");
  for (long unknowns : anySystemCase ? o.unknowns : std::vector<long>{}) {
    const ForeignLoad systemLoad;
    const System sys = buildSystem(o.sphere, unknowns, o.rhsOnes);
    systems.addRow({sys.name, std::to_string(sys.surfacePoints), std::to_string(sys.a.rows),
                    human(static_cast<double>(sys.a.nonZeros())),
                    fmt(static_cast<double>(sys.a.nonZeros()) / static_cast<double>(sys.a.rows), 1),
                    std::to_string(sys.minRow), std::to_string(sys.maxRow), sci(sys.sigma),
                    fmt(sys.assemblySeconds, 2)});
    // The machine's bandwidth drifts by tens of per cent over minutes (the host is shared), so every
    // system's fractions use a host triad measured just before it.
    TriadResult sysHost = host;
    if (needTriad) {
      sysHost = hostTriad(static_cast<std::size_t>(o.triadElements), o.triadTrials);
      triad.addRow({"host, before " + sys.name, "double", human(static_cast<double>(sysHost.elements)),
                    fmt(static_cast<double>(sysHost.elements * sysHost.bytesPerElement) / 1e6, 0),
                    fmt(sysHost.bestMs, 2), fmt(sysHost.medianMs, 2), fmt(sysHost.bestGBs, 1),
                    fmt(sysHost.medianGBs, 1)});
      progress("  host triad best " + fmt(sysHost.bestGBs, 1) + " GB/s");
    }
    for (std::size_t pi = 0; pi < o.precisions.size(); ++pi) {
      const Precision prec = o.precisions[pi];
      EigenResults eig;
      try {
        if (!o.eigen) throw std::runtime_error("skipped (--no-eigen)");
        const EigenBaseline eigen(sys.a, prec);
        if (o.runs("spmv")) {
          eig.spmv = eigen.spmv(sys.x, sys.y, o.trials);
          eig.haveSpmv = true;
          progress("  Eigen spmv " + std::string(precisionName(prec)) + ": median " + fmt(eig.spmv.ms.median, 3) +
                   " ms, " + fmt(gbs(spmvBytes(sys.a, prec), eig.spmv.ms.min), 1) + " GB/s best");
        }
        if (o.runs("cg")) {
          eig.cg = eigen.cg(sys.a, sys.b, defaultTolerance(prec), kMaxIterations, o.cgTrials);
          eig.haveCg = true;
          progress("  Eigen cg " + std::string(precisionName(prec)) + ": " + std::to_string(eig.cg.iterations) +
                   " iterations, median " + fmt(eig.cg.ms.median, 1) + " ms (" +
                   fmt(eig.cg.ms.median / std::max(1, eig.cg.iterations), 2) + " ms/it, setup " +
                   fmt(eig.cg.setupMs, 1) + " ms), rel res " + sci(eig.cg.relativeResidual));
        }
      } catch (const std::exception& e) {
        progress(std::string("  Eigen: ") + e.what());
      }
      for (std::size_t di = 0; di < devices.size(); ++di) {
        Block& blk = blockOf(di, pi);
        if (prec == Precision::Double && !blk.device.supportsDouble()) {
          blk.notes.push_back(sys.name + ": skipped, the device has no fp64");
          continue;
        }
        progress(sys.name + " on device " + blk.label.spec + " in " + precisionName(prec));
        try {
          double t0 = nowSeconds();
          const DeviceCsr a = DeviceCsr::upload(blk.device, sys.a, prec);
          blk.device.finish();
          progress("  upload " + fmt(nowSeconds() - t0, 2) + " s");
          if (o.runs("spmv")) runSpmv(blk, sys, a, eig, sysHost, o.trials);
          if (o.runs("kernels")) runKernels(blk, sys, a, o.trials);
          if (o.runs("cg")) runCg(blk, sys, a, eig, sysHost, o.cgTrials);
        } catch (const std::exception& e) {
          blk.notes.push_back(sys.name + ": failed: " + e.what());
          progress(std::string("  failed: ") + e.what());
        }
      }
    }
    progress(sys.name + " done; " + systemLoad.describe());
  }

  // Report.
  std::ostream& out = std::cout;
  const std::vector<std::pair<std::string, std::string>> buildContext = {
      {"build", build.buildType}, {"compiler", build.compiler + " " + build.flags}, {"git", build.git},
      {"host", build.cpu}, {"threads", std::to_string(build.threads)}};
  const std::string loadAfter = loadAverage();
  if (!o.csv) {
    out << "duplexfit-bench | " << build.describe() << "\n"
        << "load average (1/5/15 min) at start " << loadBefore << ", at end " << loadAfter << "; "
        << foreign.describe() << "\n\n";
  } else {
    out << "# load average at start " << loadBefore << ", at end " << loadAfter << "; " << foreign.describe()
        << "\n";
  }
  if (!systems.empty()) systems.print(out, o.csv, buildContext);
  if (!triad.empty() && o.runs("triad")) triad.print(out, o.csv, buildContext);
  for (const Block& blk : blocks) {
    if (blk.spmv.empty() && blk.kernels.empty() && blk.cg.empty() && blk.notes.empty()) continue;
    std::vector<std::pair<std::string, std::string>> context = {
        {"device", blk.label.spec},       {"device name", blk.label.name},
        {"platform", blk.label.platform}, {"driver", blk.label.driver},
        {"launch", blk.label.params},     {"precision", precisionName(blk.precision)},
        {"device triad GB/s", fmt(blk.triad.bestGBs, 1)}, {"host triad at start GB/s", fmt(host.bestGBs, 1)}};
    context.insert(context.end(), buildContext.begin(), buildContext.end());
    if (!o.csv) {
      out << headerLine(blk, build) << "\n   triad at start: host " << fmt(host.bestGBs, 1) << " GB/s, this device "
          << fmt(blk.triad.bestGBs, 1) << " GB/s (" << precisionName(blk.precision) << ")\n\n";
    }
    if (!blk.spmv.empty()) blk.spmv.print(out, o.csv, context);
    if (!blk.kernels.empty()) blk.kernels.print(out, o.csv, context);
    if (!blk.cg.empty()) blk.cg.print(out, o.csv, context);
    for (const std::string& note : blk.notes) out << (o.csv ? "# note: " : "note: ") << note << "\n";
    if (!blk.notes.empty()) out << "\n";
  }
  progress("done; " + foreign.describe());
  return 0;
}

}  // namespace

}  // namespace duplexfit::bench

int main(int argc, char** argv) {
  try {
    const duplexfit::bench::Options options = duplexfit::bench::parseOptions(argc, argv);
    return duplexfit::bench::run(options);
  } catch (const std::exception& e) {
    std::cerr << "duplexfit-bench: " << e.what() << "\n";
    return 1;
  }
}
