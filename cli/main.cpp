// duplexfit command-line tool: `devices` lists OpenCL devices; `solve` assembles and solves the Wendland
// system of one duplex-fit level for a generated sphere on the chosen device (the foundation's demo job).
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <algorithm>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/version.hpp"
#include "duplexfit/wendland.hpp"
#include "args.hpp"
#include "commands.hpp"
#include "json.hpp"

namespace {

using namespace duplexfit;
using Clock = std::chrono::steady_clock;
using cli::Args;
using cli::UsageError;
using cli::kUsage;
using cli::kDevice;
using cli::kNumerical;

const char* kHelp = R"(usage: duplexfit <command> [options]

commands:
  devices            list every compute device (spec, platform, name, type, memory, fp64, driver)
      --json           machine-readable output
  solve              assemble and solve the Wendland system of one duplex-fit level of a generated
                     sphere (surface, inward offset and off-surface points) with preconditioned CG
      --device SPEC    ref | P:D | cpu | gpu | name substring (default: $DUPLEXFIT_DEVICE, else first
                       GPU, else first CPU OpenCL device, else ref)
      --precision P    float (default) or double
      --points N       surface points on the sphere (default 20000; 3N unknowns)
      --delta D        inward offset distance, sphere radius 0.5 (default 0.05)
      --nnz K          target non-zeros per row, sets the support radius (default 45)
      --tol T          relative residual tolerance (default 1e-5 float, 1e-6 double)
      --max-iterations N  iteration cap (default 20000)
      --json           write the result as JSON on stdout
      --strict         exit with status 4 when CG does not converge
  fit INPUT          fit one field to an oriented cloud (PLY or XYZ "x y z nx ny nz"; normals outward)
                     and write zero.ply, offset1.ply, ..., field.dpxf and report.json
      --offset D[,D..] signed offsets in input units: positive = inward (hollowing), negative = outward
      --offset-rel     offsets are fractions of the bounding box's largest side
      -o DIR           output folder (default: current folder)
      --device SPEC, --precision float|double, --quiet, --strict (exit 4 if a level's CG fails or
                       the self-check below finds a component issue)
      --normals-inward the input normals point into the solid
      --validity-tol η offset validity tolerance (default 0.01)
      --levels M       number of levels (default: from the point density)
      --smoothing s    approximation mode, λ_k = s·k (default 0: interpolation)
      --fit-tol ε      stop early when the residual at the next level's centres is below ε
      --tol T, --max-iterations N   CG tolerance and cap
      --cell H / --resolution R     marching grid cell size / cells along the longest side
      --format ply|obj|stl          mesh format (default ply)
      --drop-zero-normals           drop points whose normal is zero instead of keeping them at f = 0
      --side-test      also reject offset/off-surface points behind their nearest point's tangent
                       plane (removes spurious sheets from flipped normals; see FitOptions::sideTest)
      --no-anchors     no sign anchors in empty space (winding-number classified centres at levels
                       1 .. M - --anchor-skip, default 1; they stop holes filling with phantom solid)
      --no-medial      drop offset/off-surface points rejected by the validity test instead of moving
                       them onto the medial surface of thin parts with their true distance as target
      --offset-correction  add a correction level: points Newton-projected onto each δ level, fitted
                       to the distance to the samples with support min(σ_M, |δ|/2) (experimental, off)
      --estimate-normals  the cloud has no (trusted) normals: estimate them by PCA over --normals-k K
                       neighbours (default 15) and orient them outward (as `duplexfit normals`)
      --denoise        bilateral point filter before fitting (as `duplexfit denoise`); override its
                       rules with --denoise-sigma-s, --denoise-sigma-r, --denoise-radius (input units),
                       --denoise-iterations N; the fit then defaults to --smoothing 0.2 (paper, Fig. 9)
      --separate       baseline: fit the surface from the cloud alone and each offset surface from its
                       own offset points alone (one field each: field.dpxf, field_offsetN.dpxf)
      --min-component F  drop mesh components smaller than F of their mesh's area (default 0: none)
      --min-offset-component F  the same for the offset meshes only (default 0.001)
                     Every fit checks its meshes: zero-level components that carry no input point and
                     offset components not at about |D| from the zero level are warnings, listed under
                     "self_check" in report.json; --strict then exits with status 4.
  mesh FIELD         extract one level set of a saved field: --iso V (default 0) -o OUT.ply|obj|stl
                     [--device SPEC] [--cell H | --resolution R] [--min-component F]
)";
const char* kHelpTail = R"(  --version, --help

Progress goes to stderr; --quiet silences it.
)";


std::string mib(std::uint64_t bytes) {
  std::ostringstream s;
  s << (bytes >> 20) << " MiB";
  return s.str();
}

int cmdDevices(Args& args) {
  const bool json = args.flag("json");
  args.flag("quiet");
  args.finish();
  std::vector<DeviceInfo> all = Device::enumerate();
  all.push_back(Device::reference().info());
  const std::string defaultSpec = Device::openDefault().info().spec;
  if (json) {
    cli::JsonWriter w(std::cout);
    w.beginObject().field("default", defaultSpec).key("devices").beginArray();
    for (const DeviceInfo& d : all) {
      w.beginObject()
          .field("spec", d.spec)
          .field("platform", d.platform)
          .field("name", d.name)
          .field("vendor", d.vendor)
          .field("type", deviceTypeName(d.type))
          .field("compute_units", d.computeUnits)
          .field("global_mem_bytes", d.globalMemBytes)
          .field("max_alloc_bytes", d.maxAllocBytes)
          .field("fp64", d.fp64)
          .field("opencl_c_version", d.openclCVersion)
          .field("device_version", d.deviceVersion)
          .field("driver_version", d.driverVersion)
          .endObject();
    }
    w.endArray().endObject();
    return 0;
  }
  std::cout << std::left << std::setw(6) << "spec" << std::setw(30) << "platform" << std::setw(40) << "name"
            << std::setw(6) << "type" << std::right << std::setw(5) << "CUs" << std::setw(12) << "global"
            << std::setw(12) << "max alloc" << std::setw(6) << "fp64" << "  " << std::left << std::setw(20)
            << "OpenCL C" << "driver\n";
  for (const DeviceInfo& d : all) {
    std::cout << std::left << std::setw(6) << (d.spec == defaultSpec ? d.spec + "*" : d.spec) << std::setw(30)
              << d.platform.substr(0, 29) << std::setw(40) << d.name.substr(0, 39) << std::setw(6)
              << deviceTypeName(d.type) << std::right << std::setw(5) << d.computeUnits << std::setw(12)
              << mib(d.globalMemBytes) << std::setw(12) << mib(d.maxAllocBytes) << std::setw(6)
              << (d.fp64 ? "yes" : "no") << "  " << std::left << std::setw(20) << d.openclCVersion
              << d.driverVersion << "\n";
  }
  std::cout << "(* = default device; choose with --device SPEC or DUPLEXFIT_DEVICE)\n";
  return 0;
}

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

double seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

int cmdSolve(Args& args) {
  const bool quiet = args.flag("quiet");
  const bool json = args.flag("json");
  const bool strict = args.flag("strict");
  const std::string spec = args.str("device", "");
  const Precision precision = parsePrecision(args.str("precision", "float").c_str());
  const long points = args.integer("points", 20000);
  const double delta = args.num("delta", 0.05);
  const double nnz = args.num("nnz", 45);
  SolverOptions options;
  options.relativeTolerance = args.num("tol", 0.0);
  options.maxIterations = static_cast<int>(args.integer("max-iterations", 20000));
  args.finish();
  if (points < 1 || points > 100'000'000) throw UsageError("--points must be between 1 and 1e8");
  if (!(delta > 0.0 && delta < 0.5)) throw UsageError("--delta must be in (0, 0.5) for a sphere of radius 0.5");
  if (!(nnz >= 1.0)) throw UsageError("--nnz must be at least 1");
  if (options.maxIterations < 1) throw UsageError("--max-iterations must be at least 1");
  if (options.relativeTolerance < 0.0) throw UsageError("--tol must be positive");

  auto log = [&](const std::string& s) {
    if (!quiet) std::cerr << s << std::endl;
  };
  const Device device = spec.empty() ? Device::openDefault() : Device::open(spec);
  log("device: " + device.description());
  auto t0 = Clock::now();
  device.compileKernels(precision);
  const double compileSeconds = seconds(t0);
  // Surface area π·(2r)²/… : about 3·n·(σ/(2r))²·4 neighbours within σ over the three layers.
  const int n = static_cast<int>(points);
  const double sigma = std::sqrt(nnz / (3.0 * n));
  Eigen::VectorXd targets;
  t0 = Clock::now();
  const Points centres = sphereLevel(n, delta, sigma, targets);
  log("assembling " + std::to_string(3 * n) + " unknowns, sigma " + std::to_string(sigma) + " ...");
  const CsrMatrix a = assembleWendland(centres, sigma);
  const double assemblySeconds = seconds(t0);
  const Eigen::VectorXd b = targets.array() + 1.0;  // b = t − f_0 with f_0 = −1 (docs/method.md §5)
  t0 = Clock::now();
  const DeviceCsr m = DeviceCsr::upload(device, a, precision);
  const DeviceVector db = DeviceVector::upload(device, b, precision);
  DeviceVector x(device, b.size(), precision);
  const double uploadSeconds = seconds(t0);
  options.progress = [&](int it, double res) {
    if (!quiet) std::cerr << "  CG iteration " << it << ": relative residual " << res << "\n";
    return true;
  };
  const SolveStats stats = solveCg(m, db, x, options);
  // Verify on the host in double, independently of the device arithmetic.
  const Eigen::VectorXd xs = x.download();
  const double hostResidual = (b - a.multiply(xs)).norm() / b.norm();
  log(std::string("CG ") + stopReasonName(stats.reason) + " after " + std::to_string(stats.iterations) +
      " iterations");

  if (json) {
    cli::JsonWriter w(std::cout);
    w.beginObject()
        .field("device", device.info().spec)
        .field("device_name", device.info().name)
        .field("precision", precisionName(precision))
        .field("unknowns", a.rows)
        .field("nonzeros", a.nonZeros())
        .field("sigma", sigma)
        .field("delta", delta)
        .field("kernel_build_seconds", compileSeconds)
        .field("assembly_seconds", assemblySeconds)
        .field("upload_seconds", uploadSeconds)
        .field("converged", stats.converged)
        .field("stop_reason", stopReasonName(stats.reason))
        .field("iterations", stats.iterations)
        .field("tolerance", stats.tolerance)
        .field("relative_residual", stats.relativeResidual)
        .field("host_relative_residual", hostResidual)
        .field("solve_seconds", stats.seconds)
        .field("ms_per_iteration", stats.iterations > 0 ? 1e3 * stats.seconds / stats.iterations : 0.0)
        .endObject();
  } else {
    std::cout << "device              " << device.description() << "\n"
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

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc < 2) {
      std::cerr << kHelp << kHelpTail;
      return kUsage;
    }
    const std::string cmd = argv[1];
    if (cmd == "--help" || cmd == "-h" || cmd == "help") {
      std::cout << kHelp << cli::kMeasureHelp << cli::kSectionHelp << cli::kSliceHelp << cli::kPreprocessHelp
                << kHelpTail;
      return 0;
    }
    if (cmd == "--version") {
      std::cout << "duplexfit " << DUPLEXFIT_VERSION_STRING << "\n";
      return 0;
    }
    if (cmd == "devices") {
      Args args(argc, argv, 2, {});
      return cmdDevices(args);
    }
    if (cmd == "fit") {
      Args args(argc, argv, 2, cli::kFitValued);
      return cli::cmdFit(args);
    }
    if (cmd == "mesh") {
      Args args(argc, argv, 2, cli::kMeshValued);
      return cli::cmdMesh(args);
    }
    if (cmd == "measure") {
      Args args(argc, argv, 2, cli::kMeasureValued);
      return cli::cmdMeasure(args);
    }
    if (cmd == "check") {
      Args args(argc, argv, 2, cli::kCheckValued);
      return cli::cmdCheck(args);
    }
    if (cmd == "section") {
      Args args(argc, argv, 2, cli::kSectionValued);
      return cli::cmdSection(args);
    }
    if (cmd == "slice") {
      Args args(argc, argv, 2, cli::kSliceValued);
      return cli::cmdSlice(args);
    }
    if (cmd == "denoise") {
      Args args(argc, argv, 2, cli::kDenoiseValued);
      return cli::cmdDenoise(args);
    }
    if (cmd == "normals") {
      Args args(argc, argv, 2, cli::kNormalsValued);
      return cli::cmdNormals(args);
    }
    if (cmd == "solve") {
      Args args(argc, argv, 2, {"device", "precision", "points", "delta", "nnz", "tol", "max-iterations"});
      return cmdSolve(args);
    }
    throw UsageError("unknown command '" + cmd + "' (try duplexfit --help)");
  } catch (const UsageError& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kUsage;
  } catch (const InvalidArgument& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kUsage;
  } catch (const IoError& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return cli::kIo;
  } catch (const Cancelled& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kNumerical;
  } catch (const DeviceError& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kDevice;
  } catch (const std::exception& e) {
    std::cerr << "duplexfit: " << e.what() << "\n";
    return kNumerical;
  }
}
