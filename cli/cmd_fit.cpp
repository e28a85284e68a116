// `duplexfit fit`: cloud in, one field out (or one per surface with --separate), plus meshes of the surface
// and every offset surface and a JSON report (runPipeline, writePipelineOutputs). Outputs are staged in a
// temporary folder inside the output folder and moved into place only when everything succeeded.
#include <filesystem>
#include <iomanip>
#include <iostream>

#include "commands.hpp"
#include "progress.hpp"
#include "duplexfit/pipeline.hpp"

namespace duplexfit::cli {

const std::vector<std::string> kFitValued = {"offset", "output", "device", "precision", "validity-tol", "levels",
                                             "smoothing", "fit-tol", "tol", "max-iterations", "cell", "resolution",
                                             "format", "alpha", "anchor-skip", "normals-k", "denoise-sigma-s",
                                             "denoise-sigma-r", "denoise-radius", "denoise-iterations",
                                             "min-component", "min-offset-component"};

int cmdFit(Args& args) {
  const Timer timer;
  StderrProgress progress(args.flag("quiet"));
  PipelineOptions o;
  FitOptions& fit = o.fit;
  fit.offsets = parseNumberList(args.str("offset", ""), "offset");
  fit.offsetsRelative = args.flag("offset-rel");
  fit.normalsInward = args.flag("normals-inward");
  fit.validityTolerance = args.num("validity-tol", fit.validityTolerance);
  fit.levels = static_cast<int>(args.integer("levels", 0));
  fit.alpha = args.num("alpha", fit.alpha);
  o.denoise = args.flag("denoise");
  // A denoised cloud is fitted in approximation mode, s = 0.2 as the paper's Fig. 9, unless told otherwise.
  fit.smoothing = args.num("smoothing", o.denoise ? 0.2 : 0.0);
  fit.fitTolerance = args.num("fit-tol", 0.0);
  fit.precision = parsePrecision(args.str("precision", "float").c_str());
  fit.solver.relativeTolerance = args.num("tol", 0.0);
  fit.solver.maxIterations = static_cast<int>(args.integer("max-iterations", fit.solver.maxIterations));
  fit.dropZeroNormalPoints = args.flag("drop-zero-normals");
  fit.sideTest = args.flag("side-test");
  fit.signAnchors = !args.flag("no-anchors");
  fit.medialConstraints = !args.flag("no-medial");
  fit.offsetCorrection = args.flag("offset-correction");
  fit.anchorSkipFinest = static_cast<int>(args.integer("anchor-skip", fit.anchorSkipFinest));
  o.surface.cell = args.num("cell", 0.0);
  o.surface.resolution = static_cast<int>(args.integer("resolution", 0));
  const std::string format = meshFormatOption(args);
  const bool strict = args.flag("strict");
  o.separate = args.flag("separate");
  o.selfCheck.minAreaFraction = fractionOption(args, "min-component", o.selfCheck.minAreaFraction);
  o.selfCheck.minOffsetAreaFraction = fractionOption(args, "min-offset-component", o.selfCheck.minOffsetAreaFraction);
  o.estimateNormals = args.flag("estimate-normals");
  o.normals.k = static_cast<int>(args.integer("normals-k", o.normals.k));
  o.denoiseOptions.sigmaSpatial = args.num("denoise-sigma-s", 0.0);
  o.denoiseOptions.sigmaRange = args.num("denoise-sigma-r", 0.0);
  o.denoiseOptions.radius = args.num("denoise-radius", 0.0);
  o.denoiseOptions.iterations = static_cast<int>(args.integer("denoise-iterations", 1));
  const std::filesystem::path outDir = args.str("output", ".");
  const Device device = openDevice(args.str("device", ""), progress);
  args.finish(1);
  if (args.positional().empty()) throw UsageError("fit needs an input cloud: duplexfit fit INPUT --offset D");
  const std::string input = args.positional()[0];

  StagedFolder staging(outDir);  // fails early, before any work, if the folder is unusable
  const PipelineResult result = runPipeline(device, input, o, &progress);
  writePipelineOutputs(result, staging, format);

  const FitReport& rep = result.report.fit;
  std::cout << std::setprecision(4) << "fit " << (o.separate ? "(separate) " : "") << input << ": "
            << result.report.read.points << " points, " << rep.levels << " levels, E0 " << rep.e0;
  for (std::size_t j = 0; j < rep.eDelta.size(); ++j) std::cout << ", E(" << rep.offsets[j] << ") " << rep.eDelta[j];
  std::cout << ", " << timer.seconds() << " s\n";
  const std::vector<std::string> meshNames = pipelineMeshNames(result, format);
  for (std::size_t i = 0; i < meshNames.size(); ++i) {
    const MeshTopology& t = result.surfaces[i].topology;
    std::cout << "  " << (outDir / meshNames[i]).string() << (o.separate && i > 0 ? "  offset " : "  iso ")
              << result.surfaces[i].offset << ": " << t.faces << " triangles, " << t.components << " component(s), "
              << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold") << "\n";
  }
  const SelfCheckReport& check = result.report.selfCheck;
  if (!check.ok()) std::cout << "  self-check: " << check.issues.size() << " component issue(s), listed in report.json\n";
  std::cout << " ";
  for (const std::string& f : pipelineFieldNames(result)) std::cout << " " << (outDir / f).string() << ",";
  std::cout << " " << (outDir / "report.json").string() << "\n";
  return strict && (!result.report.converged() || !check.ok()) ? kNumerical : 0;
}

}  // namespace duplexfit::cli
