// `duplexfit denoise`: the bilateral point filter (docs/method.md §9) of an oriented cloud; `duplexfit normals`:
// outward unit normals for a cloud that has none. Both write a binary PLY with normals atomically (a failed
// run leaves no output) and, with --json, a summary with the parameters used and the timings on stdout.
#include <cmath>
#include <iostream>
#include <sstream>

#include "commands.hpp"
#include "timer.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/preprocess.hpp"
#include "json.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kDenoiseValued = {"output",     "sigma-s", "sigma-r",   "radius",
                                                 "area-sigma", "iterations", "normal-k", "device", "precision"};
const std::vector<std::string> kNormalsValued = {"output", "k", "graph-k", "device", "precision"};

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

struct Common {
  bool quiet = false;
  bool json = false;
  std::string input, output;
  Precision precision = Precision::Float;
  std::string spec;
};

Common commonOptions(Args& args) {
  Common c;
  c.quiet = args.flag("quiet");
  c.json = args.flag("json");
  c.output = args.str("output", "");
  c.spec = args.str("device", "");
  c.precision = parsePrecision(args.str("precision", "float").c_str());
  return c;
}

void positional(Args& args, Common& c, const char* command) {
  args.finish(1);
  if (args.positional().empty()) {
    throw UsageError(std::string(command) + " needs an input cloud: duplexfit " + command + " INPUT -o OUT");
  }
  c.input = args.positional()[0];
  if (c.output.empty()) throw UsageError(std::string(command) + " needs an output file: -o OUT");
}

/// Opens the device and builds its kernels up front, so that the stage timings exclude the build.
Device openDevice(const Common& c, double& buildSeconds) {
  const Device d = c.spec.empty() ? Device::openDefault() : Device::open(c.spec);
  d.requirePrecision(c.precision);
  const Timer t;
  d.compileKernels(c.precision);
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

int positiveInt(Args& args, const char* key, long def, long max) {
  const long v = args.integer(key, def);
  if (v < 1 || v > max) {
    throw UsageError(std::string("option --") + key + " must be between 1 and " + std::to_string(max));
  }
  return static_cast<int>(v);
}

double length(Args& args, const char* key) {
  const double v = args.num(key, 0.0);
  if (v < 0.0) throw UsageError(std::string("option --") + key + " must be positive");
  return v;
}

}  // namespace

int cmdDenoise(Args& args) {
  const Timer start;
  Common c = commonOptions(args);
  BilateralOptions o;
  o.sigmaSpatial = length(args, "sigma-s");
  o.sigmaRange = length(args, "sigma-r");
  o.radius = length(args, "radius");
  o.areaSigma = length(args, "area-sigma");
  o.iterations = positiveInt(args, "iterations", 1, 1000);
  o.symmetricRange = args.flag("symmetric-range");
  o.reestimateNormals = args.flag("reestimate-normals");
  o.normalK = positiveInt(args, "normal-k", 15, 1000);
  o.precision = c.precision;
  positional(args, c, "denoise");
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
    JsonWriter w(std::cout);
    w.beginObject()
        .field("command", "denoise")
        .field("input", c.input)
        .field("output", c.output)
        .field("points", rep.points)
        .field("device", rep.device)
        .field("device_name", device.info().name)
        .field("precision", precisionName(rep.precision))
        .field("sigma_spatial", rep.sigmaSpatial)
        .field("sigma_range", rep.sigmaRange)
        .field("radius", rep.radius)
        .field("area_sigma", rep.areaSigma)
        .field("levels", rep.levels)
        .field("r_ave", rep.rAve)
        .field("iterations", rep.iterations)
        .field("symmetric_range", rep.symmetricRange)
        .field("normals_reestimated", rep.normalsReestimated)
        .field("mean_neighbors", rep.meanNeighbors)
        .field("isolated", rep.isolated)
        .field("moved", rep.moved)
        .field("max_displacement", rep.maxDisplacement)
        .field("mean_displacement", rep.meanDisplacement)
        .key("seconds")
        .beginObject()
        .field("kernel_build", buildSeconds)
        .field("read", readSeconds)
        .field("neighbors", rep.neighborSeconds)
        .field("filter", rep.filterSeconds)
        .field("denoise", rep.seconds)
        .field("write", writeSeconds)
        .field("total", start.seconds())
        .endObject()
        .endObject();
  } else if (!c.quiet) {
    std::cout << "denoised " << rep.points << " points on " << rep.device << " (" << precisionName(rep.precision)
              << "): " << rep.moved << " moved, max " << rep.maxDisplacement << ", mean " << rep.meanDisplacement
              << "; wrote " << c.output << "\n";
  }
  return 0;
}

int cmdNormals(Args& args) {
  const Timer start;
  Common c = commonOptions(args);
  NormalOptions o;
  o.k = positiveInt(args, "k", 15, 1000);
  o.graphK = static_cast<int>(args.integer("graph-k", 0));
  if (o.graphK < 0 || o.graphK > 1000) throw UsageError("option --graph-k must be between 1 and 1000");
  o.requireOutward = !args.flag("allow-unoriented");
  o.precision = c.precision;
  const bool keep = args.flag("keep-existing");
  positional(args, c, "normals");
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
    JsonWriter w(std::cout);
    w.beginObject()
        .field("command", "normals")
        .field("input", c.input)
        .field("output", c.output)
        .field("points", out.size())
        .field("input_had_normals", file.report.normals)
        .field("kept_existing", kept)
        .field("device", device.info().spec)
        .field("device_name", device.info().name)
        .field("precision", precisionName(c.precision))
        .field("k", rep.k)
        .field("graph_k", rep.graphK)
        .field("duplicates", rep.duplicates)
        .field("components", rep.components)
        .field("ambiguous_components", rep.ambiguousComponents)
        .field("flipped_components", rep.flippedComponents)
        .field("nested_components", rep.nestedComponents)
        .field("flipped", rep.flipped)
        .field("degenerate", rep.degenerate)
        .field("non_planar", rep.nonPlanar)
        .field("min_volume_ratio", rep.minVolumeRatio);
    if (agreeing >= 0.0) w.field("agree_with_input_normals", agreeing);
    w.key("seconds")
        .beginObject()
        .field("kernel_build", buildSeconds)
        .field("read", readSeconds)
        .field("neighbors", rep.neighborSeconds)
        .field("pca", rep.pcaSeconds)
        .field("orient", rep.orientSeconds)
        .field("normals", rep.seconds)
        .field("write", writeSeconds)
        .field("total", start.seconds())
        .endObject()
        .endObject();
  } else if (!c.quiet) {
    std::cout << (kept ? "kept the normals of " : "estimated normals of ") << out.size() << " points";
    if (!kept) std::cout << " (" << rep.components << " component(s), " << rep.seconds << " s)";
    std::cout << "; wrote " << c.output << "\n";
  }
  return 0;
}

}  // namespace duplexfit::cli
