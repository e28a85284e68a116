// `duplexfit fit`: cloud in, one field out (or one per surface with --separate), plus meshes of the surface
// and every offset surface and a JSON report (runPipeline, writePipelineOutputs). Outputs are staged in a
// temporary folder inside the output folder and moved into place only when everything succeeded.
#include <filesystem>
#include <iomanip>
#include <iostream>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/pipeline.hpp"

namespace duplexfit::cli {

int cmdFit(int argc, char** argv) {
  const Timer timer;
  CLI::App app("fit one field to an oriented cloud and write its meshes, field(s) and report.json", "fit");
  PipelineOptions o;
  FitOptions& fit = o.fit;
  DeviceOptions device;
  bool quiet = false, strict = false;
  std::string input, offsets, format = "ply", outDir = ".";
  app.add_option("INPUT", input, "PLY or XYZ \"x y z nx ny nz\" cloud, normals outward");
  app.add_option("--offset", offsets, "signed offsets D[,D..] in input units, positive = inward")->type_name("D");
  app.add_flag("--offset-rel", fit.offsetsRelative, "offsets are fractions of the bounding box's largest side");
  app.add_option("-o,--output", outDir, "output folder (default: current folder)")->type_name("DIR");
  addDeviceOptions(app, device);
  addQuiet(app, quiet);
  app.add_flag("--strict", strict, "exit with status 4 if a level's CG fails or the self-check finds an issue");
  app.add_flag("--normals-inward", fit.normalsInward, "the input normals point into the solid");
  addNumber(app, "validity-tol", fit.validityTolerance, "offset validity tolerance (default 0.01)");
  addInteger(app, "levels", fit.levels, "number of levels (default: from the point density)");
  addNumber(app, "alpha", fit.alpha, "sigma_1 = alpha * bounding-box diagonal (default 0.75)");
  addNumber(app, "smoothing", fit.smoothing, "approximation mode, lambda_k = s k (default 0; 0.2 with --denoise)");
  addNumber(app, "fit-tol", fit.fitTolerance, "stop early when the residual at the next level's centres is below it");
  addNumber(app, "tol", fit.solver.relativeTolerance, "CG relative tolerance");
  addInteger(app, "max-iterations", fit.solver.maxIterations, "CG iteration cap");
  addNumber(app, "cell", o.surface.cell, "marching grid cell size");
  addInteger(app, "resolution", o.surface.resolution, "marching grid cells along the longest side");
  app.add_option("--format", format, "mesh format: ply (default), obj or stl")->type_name("FMT");
  app.add_flag("--drop-zero-normals", fit.dropZeroNormalPoints, "drop points whose normal is zero");
  app.add_flag("--side-test", fit.sideTest, "reject offset points behind their nearest point's tangent plane");
  app.add_flag_callback("--no-anchors", [&] { fit.signAnchors = false; }, "no sign anchors in empty space");
  addInteger(app, "anchor-skip", fit.anchorSkipFinest, "sign anchors at levels 1 .. M - N (default 1)");
  app.add_flag_callback("--no-medial", [&] { fit.medialConstraints = false; }, "drop invalid offset points, not moved");
  app.add_flag("--offset-correction", fit.offsetCorrection, "add the offset-correction level (experimental)");
  app.add_flag("--estimate-normals", o.estimateNormals, "estimate and orient normals first (PCA)");
  addInteger(app, "normals-k", o.normals.k, "neighbours of the normal estimation (default 15)");
  app.add_flag("--denoise", o.denoise, "bilateral point filter before fitting");
  addNumber(app, "denoise-sigma-s", o.denoiseOptions.sigmaSpatial, "the filter's spatial width");
  addNumber(app, "denoise-sigma-r", o.denoiseOptions.sigmaRange, "the filter's range width");
  addNumber(app, "denoise-radius", o.denoiseOptions.radius, "the filter's neighbourhood radius");
  addInteger(app, "denoise-iterations", o.denoiseOptions.iterations, "filter passes (default 1)");
  app.add_flag("--separate", o.separate, "baseline: one field per surface (field.dpxf, field_offsetN.dpxf)");
  addFraction(app, "min-component", o.selfCheck.minAreaFraction, "drop components below F of the mesh's area");
  addFraction(app, "min-offset-component", o.selfCheck.minOffsetAreaFraction, "the same for offsets (0.001)");
  if (parse(app, argc, argv)) return 0;
  fit.offsets = parseNumberList(offsets, "offset");
  // A denoised cloud is fitted in approximation mode, s = 0.2 as the paper's Fig. 9, unless told otherwise.
  if (o.denoise && app.count("--smoothing") == 0) fit.smoothing = 0.2;
  fit.precision = device.precision;
  if (format != "ply" && format != "obj" && format != "stl") throw UsageError("--format must be ply, obj or stl");
  StderrProgress progress(quiet);
  const Device dev = openDevice(device.spec, progress);
  if (input.empty()) throw UsageError("fit needs an input cloud: duplexfit fit INPUT --offset D");

  StagedFolder staging(outDir);  // fails early, before any work, if the folder is unusable
  const PipelineResult result = runPipeline(dev, input, o, &progress);
  writePipelineOutputs(result, staging, format);

  const FitReport& rep = result.report.fit;
  std::cout << std::setprecision(4) << "fit " << (o.separate ? "(separate) " : "") << input << ": "
            << result.report.read.points << " points, " << rep.levels << " levels, E0 " << rep.e0;
  for (std::size_t j = 0; j < rep.eDelta.size(); ++j) std::cout << ", E(" << rep.offsets[j] << ") " << rep.eDelta[j];
  std::cout << ", " << timer.seconds() << " s\n";
  const std::filesystem::path dir = outDir;
  const std::vector<std::string> meshNames = pipelineMeshNames(result, format);
  for (std::size_t i = 0; i < meshNames.size(); ++i) {
    const MeshTopology& t = result.surfaces[i].topology;
    std::cout << "  " << (dir / meshNames[i]).string() << (o.separate && i > 0 ? "  offset " : "  iso ")
              << result.surfaces[i].offset << ": " << t.faces << " triangles, " << t.components << " component(s), "
              << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold") << "\n";
  }
  const SelfCheckReport& check = result.report.selfCheck;
  if (!check.ok()) std::cout << "  self-check: " << check.issues.size() << " component issue(s), listed in report.json\n";
  std::cout << " ";
  for (const std::string& f : pipelineFieldNames(result)) std::cout << " " << (dir / f).string() << ",";
  std::cout << " " << (dir / "report.json").string() << "\n";
  return strict && (!result.report.converged() || !check.ok()) ? kNumerical : 0;
}

}  // namespace duplexfit::cli
