// `duplexfit solve`: assembles and solves the Wendland system of one duplex-fit level for a generated
// sphere on the chosen device (the foundation's demo job), with the residual checked on the host.
#include <cmath>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/wendland.hpp"

namespace duplexfit::cli {

namespace {

// The centres of one duplex-fit level on a sphere of radius 0.5 (docs/method.md §3): n Fibonacci points,
// their copies δ inward (target δ) and σ/10 outward (target −σ/10). Returns targets t.
Points sphereLevel(int n, double delta, double sigma, Eigen::VectorXd& targets) {
  Points c(3 * n, 3);
  targets.resize(3 * n);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Eigen::RowVector3d u(r * std::cos(golden * i), r * std::sin(golden * i), z);
    c.row(i) = 0.5 * u;
    c.row(n + i) = (0.5 - delta) * u;
    c.row(2 * n + i) = (0.5 + sigma / 10) * u;
    targets[i] = 0.0;
    targets[n + i] = delta;
    targets[2 * n + i] = -sigma / 10;
  }
  return c;
}

}  // namespace

int cmdSolve(int argc, char** argv) {
  CLI::App app("assemble and solve the Wendland system of one duplex-fit level of a generated sphere", "solve");
  DeviceOptions device;
  bool quiet = false, json = false, strict = false;
  long points = 20000;
  double delta = 0.05, nnz = 45;
  SolverOptions options;
  addDeviceOptions(app, device);
  addQuiet(app, quiet);
  addJson(app, json, "write the result as JSON on stdout");
  app.add_flag("--strict", strict, "exit with status 4 when CG does not converge");
  addInteger(app, "points", points, "surface points on the sphere (default 20000; 3N unknowns)");
  addNumber(app, "delta", delta, "inward offset distance, sphere radius 0.5 (default 0.05)");
  addNumber(app, "nnz", nnz, "target non-zeros per row, sets the support radius (default 45)");
  addNumber(app, "tol", options.relativeTolerance, "relative residual tolerance (default 1e-5 float, 1e-6 double)");
  addInteger(app, "max-iterations", options.maxIterations, "iteration cap (default 20000)");
  if (parse(app, argc, argv)) return 0;
  const Precision precision = device.precision;
  if (points < 1 || points > 100'000'000) throw UsageError("--points must be between 1 and 1e8");
  if (!(delta > 0.0 && delta < 0.5)) throw UsageError("--delta must be in (0, 0.5) for a sphere of radius 0.5");
  if (!(nnz >= 1.0)) throw UsageError("--nnz must be at least 1");
  if (options.maxIterations < 1) throw UsageError("--max-iterations must be at least 1");
  if (options.relativeTolerance < 0.0) throw UsageError("--tol must be positive");

  StderrProgress log(quiet);
  const Device dev = openDevice(device.spec, log);
  Timer t0;
  dev.compileKernels(precision);
  const double compileSeconds = t0.seconds();
  // Surface area π·(2r)²/… : about 3·n·(σ/(2r))²·4 neighbours within σ over the three layers.
  const int n = static_cast<int>(points);
  const double sigma = std::sqrt(nnz / (3.0 * n));
  Eigen::VectorXd targets;
  t0.restart();
  const Points centres = sphereLevel(n, delta, sigma, targets);
  log.message("assembling " + std::to_string(3 * n) + " unknowns, sigma " + std::to_string(sigma) + " ...");
  const CsrMatrix a = assembleWendland(centres, sigma);
  const double assemblySeconds = t0.seconds();
  const Eigen::VectorXd b = targets.array() + 1.0;  // b = t − f_0 with f_0 = −1 (docs/method.md §5)
  t0.restart();
  const DeviceCsr m = DeviceCsr::upload(dev, a, precision);
  const DeviceVector db = DeviceVector::upload(dev, b, precision);
  DeviceVector x(dev, b.size(), precision);
  const double uploadSeconds = t0.seconds();
  const SolveStats stats = solveCg(m, db, x, options, nullptr, &log);
  // Verify on the host in double, independently of the device arithmetic.
  const Eigen::VectorXd xs = x.download();
  const double hostResidual = (b - a.multiply(xs)).norm() / b.norm();
  log.message(std::string("CG ") + stopReasonName(stats.reason) + " after " + std::to_string(stats.iterations) +
      " iterations");

  if (json) {
    const nlohmann::ordered_json out{
        {"device", dev.info().spec},
        {"device_name", dev.info().name},
        {"precision", precisionName(precision)},
        {"unknowns", a.rows},
        {"nonzeros", a.nonZeros()},
        {"sigma", sigma},
        {"delta", delta},
        {"kernel_build_seconds", compileSeconds},
        {"assembly_seconds", assemblySeconds},
        {"upload_seconds", uploadSeconds},
        {"converged", stats.converged},
        {"stop_reason", stopReasonName(stats.reason)},
        {"iterations", stats.iterations},
        {"tolerance", stats.tolerance},
        {"relative_residual", stats.relativeResidual},
        {"host_relative_residual", hostResidual},
        {"solve_seconds", stats.seconds},
        {"ms_per_iteration", stats.iterations > 0 ? 1e3 * stats.seconds / stats.iterations : 0.0}};
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << "device              " << dev.description() << "\n"
              << "precision           " << precisionName(precision) << "\n"
              << "unknowns            " << a.rows << " (" << n << " surface, offset and off-surface points)\n"
              << "non-zeros           " << a.nonZeros() << " (" << std::fixed << std::setprecision(1)
              << static_cast<double>(a.nonZeros()) / std::max(1, a.rows) << " per row)\n"
              << std::defaultfloat << std::setprecision(6) << "kernel build        " << compileSeconds
              << " s\n"
              << "assembly            " << assemblySeconds << " s\n"
              << "CG                  " << stopReasonName(stats.reason) << ", " << stats.iterations
              << " iterations, " << stats.seconds << " s ("
              << (stats.iterations > 0 ? 1e3 * stats.seconds / stats.iterations : 0.0) << " ms/iteration)\n"
              << "relative residual   " << stats.relativeResidual << " (device), " << hostResidual
              << " (host, double), tolerance " << stats.tolerance << "\n";
  }
  return strict && !stats.converged ? kNumerical : 0;
}

}  // namespace duplexfit::cli
