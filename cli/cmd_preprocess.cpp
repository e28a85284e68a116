// `duplexfit denoise`: the bilateral point filter (docs/method.md §9) of an oriented cloud; `duplexfit normals`:
// outward unit normals for a cloud that has none. Both write a binary PLY with normals atomically (a failed
// run leaves no output) and, with --json, a summary with the parameters used and the timings on stdout.
// The jobs and their summaries are the library's (jobs.hpp).
#include <iostream>
#include <string>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/jobs.hpp"

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
      --reestimate-normals  PCA normals of the filtered points, signed like the input's (--normals-k K, 15)
      --device SPEC, --precision float|double, --quiet, --json (summary with parameters and timings)
      --max-memory SIZE  memory budget (as fit's)
  normals INPUT      estimate outward unit normals of a cloud (normals in INPUT, if any, are ignored): PCA
                     of k neighbours, spanning-tree orientation, outward sign per connected component
      -o OUT           output cloud (binary PLY with normals; required)
      --normals-k K    neighbours of each point's PCA (default 15)
      --graph-k K      neighbours per point of the orientation graph (default K)
      --keep-existing  when INPUT has normals, write them unchanged instead of estimating
      --allow-unoriented  flat or open clouds get consistent normals without an outward side instead of
                       an error
      --device SPEC, --precision float|double, --quiet, --json (summary with parameters and timings)
      --max-memory SIZE  memory budget (as fit's)
)";

namespace {

Device open(const CloudJobArgs& c) { return c.device.spec.empty() ? Device::openDefault() : Device::open(c.device.spec); }

}  // namespace

int cmdDenoise(int argc, char** argv) {
  CLI::App app("bilateral point filter of an oriented cloud", "denoise");
  CloudJobArgs c;
  addCloudJobArgs(app, c);
  BilateralOptions o;
  addLength(app, "sigma-s", o.sigmaSpatial, "spatial width sigma_psi (default 4 R_ave)");
  addLength(app, "sigma-r", o.sigmaRange, "range width sigma_zeta on the normal offset (default 4 R_ave)");
  addLength(app, "radius", o.radius, "neighbourhood radius (default 2 sigma_psi)");
  addLength(app, "area-sigma", o.areaSigma, "sigma of the area weights (default sigma_M)");
  addPositiveInt(app, "iterations", o.iterations, 1000, "passes, each from the previous output (default 1)");
  app.add_flag("--symmetric-range", o.symmetricRange, "range weight exp(-t^2/(2 sigma_zeta^2))");
  app.add_flag("--reestimate-normals", o.reestimateNormals, "PCA normals of the filtered points");
  addPositiveInt(app, "normals-k", o.normalK, 1000, "neighbours of --reestimate-normals (default 15)");
  addMaxMemory(app, o.limits);
  if (parse(app, argc, argv)) return 0;
  o.precision = c.device.precision;
  requireCloudJobArgs(c, "denoise");
  StderrProgress progress(c.quiet);
  const DenoiseJobResult r = runDenoiseJob(open(c), c.input, o, &progress);
  OutputFolders folders = OutputFolders::forFile(c.output);
  const double writeSeconds = writeCloudOutput(c.output, r.points);
  folders.keep();
  if (c.json) {
    writeDenoiseJson(std::cout, r, c.output, writeSeconds);
  } else if (!c.quiet) {
    const BilateralReport& rep = r.report;
    std::cout << "denoised " << rep.points << " points on " << rep.device << " (" << precisionName(rep.precision)
              << "): " << rep.moved << " moved, max " << rep.maxDisplacement << ", mean " << rep.meanDisplacement
              << "; wrote " << c.output << "\n";
  }
  return 0;
}

int cmdNormals(int argc, char** argv) {
  CLI::App app("estimate outward unit normals of a cloud", "normals");
  CloudJobArgs c;
  addCloudJobArgs(app, c);
  NormalOptions o;
  bool keep = false;
  addPositiveInt(app, "normals-k", o.k, 1000, "neighbours of each point's PCA (default 15)");
  addInteger(app, "graph-k", o.graphK, "neighbours per point of the orientation graph (default K)");
  app.add_flag_callback("--allow-unoriented", [&] { o.requireOutward = false; },
                        "flat or open clouds get consistent normals without an outward side");
  app.add_flag("--keep-existing", keep, "when INPUT has normals, write them unchanged");
  addMaxMemory(app, o.limits);
  if (parse(app, argc, argv)) return 0;
  if (o.graphK < 0 || o.graphK > 1000) throw UsageError("option --graph-k must be between 1 and 1000");
  o.precision = c.device.precision;
  requireCloudJobArgs(c, "normals");
  StderrProgress progress(c.quiet);
  const NormalsJobResult r = runNormalsJob(open(c), c.input, o, keep, &progress);
  OutputFolders folders = OutputFolders::forFile(c.output);
  const double writeSeconds = writeCloudOutput(c.output, r.points);
  folders.keep();
  if (c.json) {
    writeNormalsJson(std::cout, r, c.output, writeSeconds);
  } else if (!c.quiet) {
    std::cout << (r.keptExisting ? "kept the normals of " : "estimated normals of ") << r.points.size() << " points";
    if (!r.keptExisting) std::cout << " (" << r.report.components << " component(s), " << r.report.seconds << " s)";
    std::cout << "; wrote " << c.output << "\n";
  }
  return 0;
}

}  // namespace duplexfit::cli
