// `duplexfit fit`: cloud (or mesh, sampled) in, one field out (or one per surface with --separate), plus meshes of the surface
// and every offset surface and a JSON report (runPipeline, writePipelineOutputs). Outputs are staged in a
// temporary folder inside the output folder and moved into place only when everything succeeded.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "commands.hpp"
#include "options.hpp"
#include "progress.hpp"
#include "duplexfit/communicator.hpp"
#include "duplexfit/distributed.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/pipeline.hpp"

namespace duplexfit::cli {

namespace {

/// What `check` would refuse in a pipeline mesh beside its topology and crossings ("" when nothing).
std::string qualityNote(const PipelineSurface& s) {
  std::string note;
  if (s.quality.float32DegenerateFaces > 0) {
    note += ", " + std::to_string(s.quality.float32DegenerateFaces) + " triangle(s) degenerate in float32";
  }
  if (s.tooManySlivers()) {
    note += ", " + std::to_string(s.quality.slivers) + " slivers (more than check allows)";
  }
  return note;
}

int statusOf(const std::exception& e) {
  if (dynamic_cast<const InvalidArgument*>(&e) != nullptr || dynamic_cast<const UsageError*>(&e) != nullptr) return kUsage;
  if (dynamic_cast<const IoError*>(&e) != nullptr) return kIo;
  if (dynamic_cast<const DeviceError*>(&e) != nullptr) return kDevice;
  if (dynamic_cast<const std::bad_alloc*>(&e) != nullptr) return kOutOfMemory;
  return kNumerical;
}

/// Every mesh of the run is sound (PipelineSurface::sound), as --strict asks.
bool allSound(const PipelineResult& result) {
  return std::all_of(result.surfaces.begin(), result.surfaces.end(), [](const PipelineSurface& s) { return s.sound(); });
}

}  // namespace

int cmdFit(int argc, char** argv) {
  const Timer timer;
  CLI::App app("fit one field to an oriented cloud (or a triangle mesh, sampled into one) and write its meshes, "
               "field(s) and report.json", "fit");
  PipelineOptions o;
  FitOptions& fit = o.fit;
  DeviceOptions device;
  bool quiet = false, strict = false, json = false;
  std::string input, offsets, relativeOffsets, format = "ply", outDir = ".";
  std::vector<std::string> holes;
  app.add_option("INPUT", input,
                 "PLY or XYZ \"x y z nx ny nz\" cloud, normals outward; or an STL, OBJ or PLY mesh (sampled)");
  app.add_option("--offset", offsets, "signed offsets D[,D..] in input units, positive = inward")->type_name("D");
  app.add_option("--offset-rel", relativeOffsets,
                 "signed offsets F[,F..] as fractions of the bounding box's largest side (instead of --offset)")
      ->type_name("F");
  app.add_option("-o,--output", outDir, "output folder, created when missing (default: current folder)")->type_name("DIR");
  addJson(app, json, "print report.json on stdout instead of the summary");
  addDeviceOptions(app, device);
  addQuiet(app, quiet);
  app.add_flag("--strict", strict, "exit with status 4 if a level's CG fails, the self-check finds an issue, a mesh "
               "written is not a closed 2-manifold free of self-intersections or the shell is not a valid solid; an "
               "open or non-manifold mesh input is an error (status 1)");
  app.add_flag("--normals-inward", fit.normalsInward, "the input normals point into the solid");
  addNumber(app, "validity-tol", fit.validityTolerance, "offset validity tolerance (default 0.01)");
  addInteger(app, "levels", fit.levels, "number of levels (default: from the point density)");
  addNumber(app, "alpha", fit.alpha, "sigma_1 = alpha * bounding-box diagonal (default 0.75)");
  addNumber(app, "smoothing", fit.smoothing,
            "approximation mode, lambda_k = s k (default 0; 0.2 with --denoise or a noisy-looking cloud)");
  addNumber(app, "fit-tol", fit.fitTolerance, "stop early when the residual at the next level's centres is below it");
  addNumber(app, "tol", fit.solver.relativeTolerance, "CG relative tolerance");
  addNumber(app, "coarse-tol", fit.coarseTolerance, "CG relative tolerance of the levels below the finest");
  addInteger(app, "max-iterations", fit.solver.maxIterations, "CG iteration cap");
  app.add_option_function<std::string>(
         "--preconditioner",
         [&fit](const std::string& v) { fit.preconditioner = parsePreconditionerKind(v); },
         "the level solves' preconditioner: fsai (default), block-jacobi or jacobi")
      ->check(CLI::IsMember(std::vector<std::string>{preconditionerKindName(PreconditionerKind::Fsai),
                                                     preconditionerKindName(PreconditionerKind::BlockJacobi),
                                                     preconditionerKindName(PreconditionerKind::Jacobi)}))
      ->type_name("P");
  app.add_option_function<std::string>(
         "--assembly", [&fit](const std::string& v) { fit.assembly = parseAssemblyPlace(v); },
         "where the level matrices are assembled: auto (default: the device when it is a GPU), host or device "
         "(an OpenCL device with double precision; the same matrices)")
      ->check(CLI::IsMember(std::vector<std::string>{assemblyPlaceName(AssemblyPlace::Auto),
                                                     assemblyPlaceName(AssemblyPlace::Host),
                                                     assemblyPlaceName(AssemblyPlace::Device)}))
      ->type_name("WHERE");
  addNumber(app, "fsai-threshold", fit.fsaiThreshold,
            "FSAI keeps the couplings |a_ij| >= T sqrt(a_ii a_jj), 0 .. 1 (default 0.2)");
  addNumber(app, "cell", o.surface.cell, "marching grid cell size");
  addInteger(app, "resolution", o.surface.resolution, "marching grid cells along the longest side");
  addMeshFinishOptions(app, o.surface.finish);
  addRefineOptions(app, o.surface);
  addMaxMemory(app, o.limits);
  app.add_option("--format", format, "mesh format: ply (default), obj, stl or 3mf (3mf: builds with lib3mf)")->type_name("FMT");
  app.add_flag("--drop-zero-normals", fit.dropZeroNormalPoints, "drop points whose normal is zero");
  app.add_flag("--side-test", fit.sideTest, "reject offset points behind their nearest point's tangent plane");
  app.add_flag_callback("--no-crease-test", [&] { fit.creaseTest = false; },
                        "keep offset points within half their step of a tangent plane across a convex edge");
  app.add_flag_callback("--no-anchors", [&] { fit.signAnchors = false; }, "no sign anchors in empty space");
  addInteger(app, "anchor-skip", fit.anchorSkipFinest, "sign anchors at levels 1 .. M - N (default 1)");
  app.add_flag_callback("--no-overshoot-check", [&] { fit.overshootCheck = false; },
                        "no check of the finest level between sparse samples (else points D off the surface, "
                        "where f is less than D/2 off it and no sample is nearer, join the level)");
  addNumber(app, "overshoot-spacings", fit.overshootSpacings,
            "D of the overshoot check in median sample spacings (default 1.5)")
      ->check([](const std::string& v) {
        const double d = parseFinite(v, "overshoot-spacings");
        if (!(d > 0.0)) throw UsageError("option --overshoot-spacings must be positive");
        return std::string();
      });
  addInteger(app, "overshoot-rounds", fit.overshootRounds, "solves of the finest level the overshoot check may add (default 2)");
  app.add_flag_callback("--no-phantom-repair", [&] { o.repairPhantoms = false; },
                        "keep zero-level components without input points that the winding number calls empty "
                        "space (else removed from the field and the mesh)");
  app.add_flag_callback("--no-medial", [&] { fit.medialConstraints = false; }, "drop invalid offset points, not moved");
  app.add_flag("--offset-correction", fit.offsetCorrection, "add the offset-correction level (experimental)");
  app.add_flag("--estimate-normals", o.estimateNormals, "estimate and orient normals first (PCA)");
  addInteger(app, "normals-k", o.normals.k, "neighbours of the normal estimation (default 15)");
  CLI::Option* denoiseFlag = app.add_flag("--denoise", o.denoise, "bilateral point filter before fitting");
  app.add_flag_callback("--no-denoise", [&] { o.denoiseWhenNoisy = false; },
                        "interpolate a cloud that looks noisy as it is (no automatic filter)")
      ->excludes(denoiseFlag);
  app.add_flag("--remove-outliers", o.removeOutliers, "drop far outliers (reported in report.json) before fitting");
  addNumber(app, "denoise-sigma-s", o.denoiseOptions.sigmaSpatial, "the filter's spatial width");
  addNumber(app, "denoise-sigma-r", o.denoiseOptions.sigmaRange, "the filter's range width");
  addNumber(app, "denoise-radius", o.denoiseOptions.radius, "the filter's neighbourhood radius");
  addInteger(app, "denoise-iterations", o.denoiseOptions.iterations, "filter passes (default 1)");
  app.add_flag("--separate", o.separate, "baseline: one field per surface (field.dpxf, field_offsetN.dpxf)");
  addFraction(app, "min-component", o.selfCheck.minAreaFraction, "drop components below F of the mesh's area");
  addFraction(app, "min-offset-component", o.selfCheck.minOffsetAreaFraction, "the same for offsets (0.001)");
  app.add_flag("--shell", o.shell, "also shell.EXT: the zero level and the inward offset as one closed solid");
  addDrainHoles(app, holes);
  std::string inputType = "auto";
  app.add_option("--input-type", inputType, "auto (default: .stl, .obj and .ply with faces are meshes), cloud or mesh")
      ->type_name("T")
      ->group("Mesh input");
  MeshSampleOptions& sampling = o.meshSampling;
  std::size_t samplePoints = 0;
  addInteger(app, "sample-points", samplePoints, "samples of a mesh input (default: spacing = largest side / 150)")
      ->group("Mesh input");
  addLength(app, "sample-spacing", sampling.spacing, "mean sample spacing of a mesh input, in input units");
  app.get_option("--sample-spacing")->group("Mesh input")->type_name("H");
  app.add_flag_callback("--mesh-reorient", [&] { sampling.orientation = MeshOrientation::Reorient; },
                        "orient an inconsistently oriented mesh's faces consistently (else it is an error)")
      ->group("Mesh input");
  std::string distributedMode;
  DistributedOptions dist;
  app.add_option("--distributed", distributedMode,
                 "fit over the MPI ranks of `mpirun -np P duplexfit fit ...` by spatial blocks: local (restricted "
                 "additive Schwarz; the default under mpirun with P > 1) or exact (distributed PCG on each level's global "
                 "system: the single-process fit's solution)")
      ->type_name("MODE")->group("Distributed (MPI)");
  addNumber(app, "halo", dist.halo, "local mode: halo of a block's system in supports sigma_k (default 4)")->group("Distributed (MPI)");
  addInteger(app, "blocks", dist.blocks,
             "fit by N spatial blocks solved one after another (out of core: about one block's system in memory "
             "at a time; local mode); under mpirun the N blocks are shared by the ranks")
      ->group("Distributed (MPI)");
  addInteger(app, "coarse-points", dist.coarsePoints,
             "levels with at most N level points are solved whole on every rank (default 8192)")
      ->group("Distributed (MPI)");
  if (parse(app, argc, argv)) return 0;
  const bool severalRanks = launchedWithSeveralRanks();
  if (!distributedMode.empty() && distributedMode != "local" && distributedMode != "exact") {
    throw UsageError("--distributed must be local or exact");
  }
  const bool blocked = app.count("--blocks") > 0;
  if (blocked && dist.blocks < 1) throw UsageError("option --blocks must be at least 1");
  if (blocked && distributedMode == "exact") {
    throw UsageError("--blocks solves the blocks one after another (local mode): it does not combine with --distributed exact");
  }
  if (distributedMode.empty() && (app.count("--halo") > 0 || app.count("--coarse-points") > 0) && !severalRanks && !blocked) {
    throw UsageError("--halo and --coarse-points apply to the distributed fit (--distributed local, --blocks N, or mpirun -np P)");
  }
  const bool distributed = !distributedMode.empty() || severalRanks || blocked;
  if (distributed && severalRanks && !mpiBuilt()) {
    throw UsageError("launched with several MPI ranks, but this duplexfit was built without MPI (install "
                     "libopenmpi-dev and rebuild): every rank would fit the whole cloud");
  }
  dist.mode = distributedMode == "exact" ? DistributedMode::Exact : DistributedMode::Local;
  if (!(dist.halo > 0.0)) throw UsageError("option --halo must be positive");
  if (inputType == "auto") {
    o.input = InputKind::Auto;
  } else if (inputType == "cloud") {
    o.input = InputKind::Cloud;
  } else if (inputType == "mesh") {
    o.input = InputKind::Mesh;
  } else {
    throw UsageError("--input-type must be auto, cloud or mesh");
  }
  if (app.count("--sample-points") > 0 && samplePoints < 10) throw UsageError("option --sample-points must be >= 10");
  if (samplePoints > 0 && sampling.spacing > 0.0) throw UsageError("give --sample-points or --sample-spacing, not both");
  if (app.count("--sample-spacing") > 0 && !(sampling.spacing > 0.0)) {
    throw UsageError("option --sample-spacing must be positive");
  }
  sampling.points = samplePoints;
  sampling.strict = strict;
  if (!offsets.empty() && !relativeOffsets.empty()) {
    throw UsageError("give the offsets either in input units (--offset D) or relative to the part (--offset-rel F), not both");
  }
  fit.offsetsRelative = !relativeOffsets.empty();
  fit.offsets = fit.offsetsRelative ? parseNumberList(relativeOffsets, "offset-rel") : parseNumberList(offsets, "offset");
  checkOutputFolderName(outDir, "fit");
  for (const std::string& h : holes) parseDrainHoleSpec(h, o.shellOptions);
  o.shell = o.shell || o.shellOptions.drained();  // holes imply --shell
  // A filtered cloud is fitted with s = 0.2 (the library's rule, the paper's Fig. 9) unless --smoothing says
  // otherwise, 0 included.
  if (app.count("--smoothing") != 0) o.denoiseSmoothing = fit.smoothing;
  fit.precision = device.precision;
  if (format != "ply" && format != "obj" && format != "stl" && format != "3mf") {
    throw UsageError("--format must be ply, obj, stl or 3mf");
  }
  if (format == "3mf" && !mesh3mfAvailable()) {
    throw UsageError("--format 3mf: this build of duplexfit has no lib3mf (Debian: lib3mf-dev)");
  }
  std::shared_ptr<Communicator> comm;
  if (distributed) {
    comm = mpiBuilt() ? mpiWorldCommunicator() : std::shared_ptr<Communicator>(makeSerialCommunicator());
  }
  const bool rank0 = !comm || comm->rank() == 0;
  StderrProgress progress(quiet || !rank0);  // one rank speaks
  if (input.empty()) throw UsageError("fit needs an input cloud: duplexfit fit INPUT --offset D");

  PipelineResult result;
  if (comm) {
    // A rank that fails stops every rank: its message, then MPI_Abort (nothing is written: rank 0 commits
    // the output folder only after the whole fit).
    try {
      const Device dev = openDevice(device.spec, progress);
      std::optional<StagedFolder> staging;
      if (rank0) staging.emplace(outDir);
      result = runDistributedPipeline(dev, *comm, input, o, dist, rank0 ? &progress : nullptr);
      if (rank0) writePipelineOutputs(result, *staging, format);
      comm->barrier();
    } catch (const std::exception& e) {
      if (comm->size() > 1) {
        std::cerr << "duplexfit: rank " << comm->rank() << " of " << comm->size() << ": " << e.what()
                  << "; stopping every rank, nothing was written" << std::endl;
        comm->abort(statusOf(e));
      }
      throw;
    }
    if (!rank0) return 0;
  } else {
    const Device dev = openDevice(device.spec, progress);
    StagedFolder staging(outDir);  // fails early, before any work, if the folder is unusable
    result = runPipeline(dev, input, o, &progress);
    writePipelineOutputs(result, staging, format);
  }

  if (json) {
    // Exactly what was committed.
    std::ifstream committed(std::filesystem::path(outDir) / "report.json", std::ios::binary);
    std::cout << committed.rdbuf();
    const bool shellValid = !result.shell || result.shell->report.valid();
    return strict && (!result.report.converged() || !result.report.selfCheck.ok() || !allSound(result) || !shellValid)
               ? kNumerical
               : 0;
  }
  const FitReport& rep = result.report.fit;
  std::cout << std::setprecision(4) << "fit " << (o.separate ? "(separate) " : "") << input << ": ";
  if (const std::optional<MeshSampleReport>& mesh = result.report.mesh) {
    std::cout << "mesh of " << mesh->topology.faces << " triangles sampled into ";
  }
  std::cout << result.report.read.points << " points, " << rep.levels << " levels, E0 " << rep.e0;
  for (std::size_t j = 0; j < rep.eDelta.size(); ++j) std::cout << ", E(" << rep.offsets[j] << ") " << rep.eDelta[j];
  std::cout << ", " << timer.seconds() << " s\n";
  const std::filesystem::path dir = outDir;
  const std::vector<std::string> meshNames = pipelineMeshNames(result, format);
  for (std::size_t i = 0; i < meshNames.size(); ++i) {
    const MeshTopology& t = result.surfaces[i].topology;
    std::cout << "  " << (dir / meshNames[i]).string() << (o.separate && i > 0 ? "  offset " : "  iso ")
              << result.surfaces[i].offset << ": " << t.faces << " triangles, " << t.components << " component(s), "
              << (t.watertight() && t.manifold() ? "watertight 2-manifold" : "NOT watertight/manifold")
              << crossingNote(result.surfaces[i].finish.project) << qualityNote(result.surfaces[i]) << "\n";
  }
  if (result.shell) {
    const ShellReport& s = result.shell->report;
    std::cout << "  " << (dir / pipelineShellName(format)).string() << "  iso 0 and " << s.offset << ": "
              << s.topology.faces << " triangles, " << (s.valid() ? "valid solid" : "NOT a valid solid")
              << ", volume " << s.volume << " (zero - offset " << s.zeroMinusOffsetVolume() << "), "
              << s.drainHoles.size() << " drain hole(s)\n";
  }
  if (result.report.mesh && !result.report.mesh->warnings.empty()) {
    std::cout << "  input mesh: " << result.report.mesh->warnings.size() << " warning(s), listed in report.json\n";
  }
  const SelfCheckReport& check = result.report.selfCheck;
  if (!check.ok()) std::cout << "  self-check: " << check.issues.size() << " component issue(s), listed in report.json\n";
  for (const SurfaceSelfCheck& s : check.surfaces) {
    // A shell wall below half the offset: the δ level pulled towards the surface somewhere (report.json
    // self_check.surfaces[j].thinnest_wall, always given).
    if (s.iso == 0.0 || !(s.thinnestWall < 0.5 * std::abs(s.iso))) continue;
    std::cout << "  self-check: " << meshNames[static_cast<std::size_t>(s.surface)] << " comes within "
              << s.thinnestWall << " (" << std::lround(100.0 * s.thinnestWall / std::abs(s.iso)) << "% of |offset|) of "
              << meshNames[0] << " at (" << s.thinnestWallAt.x() << ", " << s.thinnestWallAt.y() << ", "
              << s.thinnestWallAt.z() << ")\n";
  }
  std::cout << " ";
  for (const std::string& f : pipelineFieldNames(result)) std::cout << " " << (dir / f).string() << ",";
  std::cout << " " << (dir / "report.json").string() << "\n";
  const bool shellOk = !result.shell || result.shell->report.valid();
  return strict && (!result.report.converged() || !check.ok() || !allSound(result) || !shellOk) ? kNumerical : 0;
}

}  // namespace duplexfit::cli
