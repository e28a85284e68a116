// `duplexfit denoise`: the bilateral point filter (docs/method.md §9) of an oriented cloud; `duplexfit normals`:
// outward unit normals for a cloud that has none. Both write a binary PLY with normals atomically (a failed
// run leaves no output) and, with --json, a summary with the parameters used and the timings on stdout.
#include <cmath>
#include <iostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "options.hpp"
#include "timer.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/preprocess.hpp"

namespace duplexfit::cli {

const char* const kPreprocessHelp = R"(  denoise INPUT      bilateral point filter of an oriented cloud (docs/method.md §9): each point moves to the
                     weighted mean of its projections onto its neighbours' tangent planes; normals kept
      -o OUT           output cloud (binary PLY with normals; required)
      --sigma-s S      spatial width sigma_psi (default 4 R_ave, R_ave = mean sqrt(sigma_M^2 / N(q)))
      --sigma-r S      range width sigma_zeta on the normal offset (default 4 R_ave)
      --radius R       neighbourhood radius (default 2 sigma_psi)
      --area-sigma S   sigma of the area weights sigma^2/N(q) (default sigma_M, the fit's finest support)
      --iterations N   passes, each from the previous output (default 1)
      --symmetric-range  range weight exp(-t^2/(2 sigma_zeta^2)) instead of exp(-t^2/sigma_zeta^2)
      --reestimate-normals  PCA normals of the filtered points, signed like the input's (--normal-k K, 15)
      --device SPEC, --precision float|double, --quiet, --json (summary with parameters and timings)
  normals INPUT      estimate outward unit normals of a cloud (normals in INPUT, if any, are ignored): PCA
                     of k neighbours, spanning-tree orientation, outward sign per connected component
      -o OUT           output cloud (binary PLY with normals; required)
      --k K            neighbours of each point's PCA (default 15)
      --graph-k K      neighbours per point of the orientation graph (default K)
      --keep-existing  when INPUT has normals, write them unchanged instead of estimating
      --allow-unoriented  flat or open clouds get consistent normals without an outward side instead of
                       an error
      --device SPEC, --precision float|double, --quiet, --json (summary with parameters and timings)
)";

namespace {

using Json = nlohmann::ordered_json;

struct Common {
  bool quiet = false;
  bool json = false;
  std::string input, output;
  DeviceOptions device;
};

/// INPUT, -o OUT and the shared groups (device + precision, quiet, json).
void commonOptions(CLI::App& app, Common& c) {
  app.add_option("INPUT", c.input, "input cloud (PLY or XYZ)");
  app.add_option("-o,--output", c.output, "output cloud (binary PLY with normals; required)")->type_name("OUT");
  addDeviceOptions(app, c.device);
  addQuiet(app, c.quiet);
  addJson(app, c.json, "summary with parameters and timings on stdout");
}

void positional(const Common& c, const char* command) {
  if (c.input.empty()) {
    throw UsageError(std::string(command) + " needs an input cloud: duplexfit " + command + " INPUT -o OUT");
  }
  if (c.output.empty()) throw UsageError(std::string(command) + " needs an output file: -o OUT");
}

/// Opens the device and builds its kernels up front, so that the stage timings exclude the build.
Device openDevice(const Common& c, double& buildSeconds) {
  const Device d = c.device.spec.empty() ? Device::openDefault() : Device::open(c.device.spec);
  d.requirePrecision(c.device.precision);
  const Timer t;
  d.compileKernels(c.device.precision);
  buildSeconds = t.seconds();
  return d;
}

/// Reads the input cloud, normals optional (each command decides what it needs).
PointCloudFile readInput(const Common& c, double& seconds) {
  const Timer t;
  PointReadOptions ro;
  ro.requireNormals = false;
  PointCloudFile file = readPointCloudWithReport(c.input, ro);
  seconds = t.seconds();
  return file;
}

/// --name N, an integer in [1, max].
void addPositiveInt(CLI::App& app, const std::string& name, int& target, int max, const std::string& help) {
  addInteger(app, name, target, help)->check([name, max](const std::string& v) {
    const double d = parseFinite(v, name);
    if (d < 1 || d > max) throw UsageError("option --" + name + " must be between 1 and " + std::to_string(max));
    return std::string();
  });
}

/// --name L, a length ≥ 0 (0: the rule's default).
void addLength(CLI::App& app, const std::string& name, double& target, const std::string& help) {
  addNumber(app, name, target, help)->check([name](const std::string& v) {
    if (parseFinite(v, name) < 0.0) throw UsageError("option --" + name + " must be positive");
    return std::string();
  });
}

}  // namespace

int cmdDenoise(int argc, char** argv) {
  const Timer start;
  CLI::App app("bilateral point filter of an oriented cloud", "denoise");
  Common c;
  commonOptions(app, c);
  BilateralOptions o;
  addLength(app, "sigma-s", o.sigmaSpatial, "spatial width sigma_psi (default 4 R_ave)");
  addLength(app, "sigma-r", o.sigmaRange, "range width sigma_zeta on the normal offset (default 4 R_ave)");
  addLength(app, "radius", o.radius, "neighbourhood radius (default 2 sigma_psi)");
  addLength(app, "area-sigma", o.areaSigma, "sigma of the area weights (default sigma_M)");
  addPositiveInt(app, "iterations", o.iterations, 1000, "passes, each from the previous output (default 1)");
  app.add_flag("--symmetric-range", o.symmetricRange, "range weight exp(-t^2/(2 sigma_zeta^2))");
  app.add_flag("--reestimate-normals", o.reestimateNormals, "PCA normals of the filtered points");
  addPositiveInt(app, "normal-k", o.normalK, 1000, "neighbours of --reestimate-normals (default 15)");
  if (parse(app, argc, argv)) return 0;
  o.precision = c.device.precision;
  positional(c, "denoise");
  auto log = [&](const std::string& s) {
    if (!c.quiet) std::cerr << s << std::endl;
  };
  double buildSeconds = 0.0, readSeconds = 0.0;
  const Device device = openDevice(c, buildSeconds);
  log("device: " + device.description());
  const PointCloudFile file = readInput(c, readSeconds);
  if (!file.report.normals) {
    throw InvalidArgument(c.input + ": the cloud has no normals; the bilateral filter projects onto the tangent "
                                    "planes they define (run `duplexfit normals " +
                          c.input + " -o WITH_NORMALS.ply` first)");
  }
  log("read " + std::to_string(file.points.size()) + " points from " + c.input);

  BilateralReport rep;
  const PointSet out = bilateralFilter(file.points, o, device, &rep);
  log("filtered: sigma_s " + std::to_string(rep.sigmaSpatial) + ", sigma_r " + std::to_string(rep.sigmaRange) +
      ", radius " + std::to_string(rep.radius) + ", " + std::to_string(rep.meanNeighbors) + " neighbours a point, " +
      std::to_string(rep.seconds) + " s");

  const Timer t;
  writePointCloud(c.output, out);
  const double writeSeconds = t.seconds();

  if (c.json) {
    const Json summary{{"command", "denoise"},
                       {"input", c.input},
                       {"output", c.output},
                       {"points", rep.points},
                       {"device", rep.device},
                       {"device_name", device.info().name},
                       {"precision", precisionName(rep.precision)},
                       {"sigma_spatial", rep.sigmaSpatial},
                       {"sigma_range", rep.sigmaRange},
                       {"radius", rep.radius},
                       {"area_sigma", rep.areaSigma},
                       {"levels", rep.levels},
                       {"r_ave", rep.rAve},
                       {"iterations", rep.iterations},
                       {"symmetric_range", rep.symmetricRange},
                       {"normals_reestimated", rep.normalsReestimated},
                       {"mean_neighbors", rep.meanNeighbors},
                       {"isolated", rep.isolated},
                       {"moved", rep.moved},
                       {"max_displacement", rep.maxDisplacement},
                       {"mean_displacement", rep.meanDisplacement},
                       {"seconds",
                        {{"kernel_build", buildSeconds},
                         {"read", readSeconds},
                         {"neighbors", rep.neighborSeconds},
                         {"filter", rep.filterSeconds},
                         {"denoise", rep.seconds},
                         {"write", writeSeconds},
                         {"total", start.seconds()}}}};
    std::cout << summary.dump(2, ' ', false, Json::error_handler_t::replace) << "\n";
  } else if (!c.quiet) {
    std::cout << "denoised " << rep.points << " points on " << rep.device << " (" << precisionName(rep.precision)
              << "): " << rep.moved << " moved, max " << rep.maxDisplacement << ", mean " << rep.meanDisplacement
              << "; wrote " << c.output << "\n";
  }
  return 0;
}

int cmdNormals(int argc, char** argv) {
  const Timer start;
  CLI::App app("estimate outward unit normals of a cloud", "normals");
  Common c;
  commonOptions(app, c);
  NormalOptions o;
  bool keep = false;
  addPositiveInt(app, "k", o.k, 1000, "neighbours of each point's PCA (default 15)");
  addInteger(app, "graph-k", o.graphK, "neighbours per point of the orientation graph (default K)");
  app.add_flag_callback("--allow-unoriented", [&] { o.requireOutward = false; },
                        "flat or open clouds get consistent normals without an outward side");
  app.add_flag("--keep-existing", keep, "when INPUT has normals, write them unchanged");
  if (parse(app, argc, argv)) return 0;
  if (o.graphK < 0 || o.graphK > 1000) throw UsageError("option --graph-k must be between 1 and 1000");
  o.precision = c.device.precision;
  positional(c, "normals");
  auto log = [&](const std::string& s) {
    if (!c.quiet) std::cerr << s << std::endl;
  };
  double buildSeconds = 0.0, readSeconds = 0.0;
  const Device device = openDevice(c, buildSeconds);
  log("device: " + device.description());
  const PointCloudFile file = readInput(c, readSeconds);
  log("read " + std::to_string(file.points.size()) + " points from " + c.input +
      (file.report.normals ? " (with normals)" : " (no normals)"));

  NormalReport rep;
  PointSet out;
  bool kept = false;
  double agreeing = -1.0;  // share of the input's nonzero normals within 90 degrees of the estimate
  if (keep && file.report.normals) {
    out = file.points;
    kept = true;
    log("kept the input's normals (--keep-existing)");
  } else {
    try {
      out = estimateNormals(file.points.positions(), o, device, &rep);
    } catch (const InvalidArgument& e) {
      throw InvalidArgument(c.input + ": " + e.what());
    }
    log("estimated normals: k " + std::to_string(rep.k) + ", " + std::to_string(rep.components) + " component(s), " +
        std::to_string(rep.flippedComponents) + " flipped outward, " + std::to_string(rep.degenerate) +
        " degenerate, " + std::to_string(rep.seconds) + " s");
    if (rep.ambiguousComponents > 0) {
      log("warning: " + std::to_string(rep.ambiguousComponents) +
          " component(s) enclose no volume: their normals are consistent but not necessarily outward");
    }
    if (file.report.normals) {
      std::size_t with = 0, agree = 0;
      for (Eigen::Index i = 0; i < out.positions().rows(); ++i) {
        if (file.points.normals().row(i).squaredNorm() == 0.0) continue;
        ++with;
        agree += out.normals().row(i).dot(file.points.normals().row(i)) > 0.0 ? 1 : 0;
      }
      if (with > 0) agreeing = static_cast<double>(agree) / static_cast<double>(with);
    }
  }

  const Timer t;
  writePointCloud(c.output, out);
  const double writeSeconds = t.seconds();

  if (c.json) {
    Json summary{{"command", "normals"},
                 {"input", c.input},
                 {"output", c.output},
                 {"points", out.size()},
                 {"input_had_normals", file.report.normals},
                 {"kept_existing", kept},
                 {"device", device.info().spec},
                 {"device_name", device.info().name},
                 {"precision", precisionName(c.device.precision)},
                 {"k", rep.k},
                 {"graph_k", rep.graphK},
                 {"duplicates", rep.duplicates},
                 {"components", rep.components},
                 {"ambiguous_components", rep.ambiguousComponents},
                 {"flipped_components", rep.flippedComponents},
                 {"nested_components", rep.nestedComponents},
                 {"flipped", rep.flipped},
                 {"degenerate", rep.degenerate},
                 {"non_planar", rep.nonPlanar},
                 {"min_volume_ratio", rep.minVolumeRatio}};
    if (agreeing >= 0.0) summary["agree_with_input_normals"] = agreeing;
    summary["seconds"] = Json{{"kernel_build", buildSeconds}, {"read", readSeconds},
                              {"neighbors", rep.neighborSeconds}, {"pca", rep.pcaSeconds},
                              {"orient", rep.orientSeconds},     {"normals", rep.seconds},
                              {"write", writeSeconds},           {"total", start.seconds()}};
    std::cout << summary.dump(2, ' ', false, Json::error_handler_t::replace) << "\n";
  } else if (!c.quiet) {
    std::cout << (kept ? "kept the normals of " : "estimated normals of ") << out.size() << " points";
    if (!kept) std::cout << " (" << rep.components << " component(s), " << rep.seconds << " s)";
    std::cout << "; wrote " << c.output << "\n";
  }
  return 0;
}

}  // namespace duplexfit::cli
