// The whole job of `duplexfit fit` as one library call: read → (estimate normals) → merge duplicates →
// (denoise) → fit (duplex, or the separate baseline) → surface extraction → clean-up and self-check →
// topology, and the report; plus writing every output (meshes, fields, report.json) to a folder atomically.
// `duplexfit mesh`'s job (one level set of a saved field) is runMeshPipeline.
//
//     const duplexfit::Device device = duplexfit::Device::openDefault();
//     duplexfit::PipelineOptions options;
//     options.fit.offsets = {0.02};
//     const duplexfit::PipelineResult result = duplexfit::runPipeline(device, "cloud.ply", options);
//     duplexfit::writePipelineOutputs(result, "out");  // zero.ply, offset1.ply, field.dpxf, report.json
//
// With options.shell, also the printable shell (shell.hpp) of the zero level and the smallest inward
// offset, with drain holes cut in the field (shell.ply, report.json's "shell"); `duplexfit mesh --shell`'s
// job, the shell of a saved field, is runShellPipeline.
#pragma once

#include <cstddef>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/distributed.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh_sampling.hpp"
#include "duplexfit/phantom_repair.hpp"
#include "duplexfit/point_set.hpp"
#include "duplexfit/preprocess.hpp"
#include "duplexfit/self_check.hpp"
#include "duplexfit/shell.hpp"
#include "duplexfit/surfaces.hpp"

namespace duplexfit {

struct PipelineOptions {
  /// What the input file holds: Auto (detectInputKind: .stl, .obj and a .ply with faces are meshes), Cloud
  /// or Mesh. A mesh is sampled into an oriented cloud first (sampleMeshCloud with meshSampling).
  InputKind input = InputKind::Auto;
  /// How a mesh input is sampled and checked. With estimateNormals its orientation policy Require becomes
  /// Keep (the face normals are replaced anyway).
  MeshSampleOptions meshSampling{};
  /// The fit (offsets, levels, solver, ...). Its precision is used by every stage (normals, denoise,
  /// surfaces): the precision fields of the other options are ignored.
  FitOptions fit{};
  /// The separate-fit baseline (fitSeparate): one field per surface instead of one duplex field.
  bool separate = false;
  /// Estimate the normals (estimateNormals) instead of reading them; the input then needs none.
  bool estimateNormals = false;
  NormalOptions normals{};
  /// Bilateral point filter (bilateralFilter) after the normals, before the fit. A filtered cloud is fitted
  /// with fit.smoothing or, when that is 0, denoiseSmoothing (the paper's s = 0.2, Fig. 9).
  bool denoise = false;
  BilateralOptions denoiseOptions{};
  double denoiseSmoothing = 0.2;
  /// Without `denoise`: filter the points all the same when the input looks noisy (the estimate every run
  /// makes, PipelineReport::noise, NoiseEstimate::noisy()), docs/method.md §9: an interpolating fit follows
  /// the noise (bumpy surfaces, dozens of small bubble components, offsets 4× farther off than the two-step
  /// pipeline's on the shared noisy clouds). false (the CLI's --no-denoise): the field interpolates the noisy
  /// points, with a hint on the log. The distributed pipeline does neither (it does not estimate the noise).
  bool denoiseWhenNoisy = true;
  /// Far outliers (findOutliers) are always looked for and reported; with removeOutliers they are dropped
  /// before anything else, otherwise a warning names them.
  bool removeOutliers = false;
  OutlierOptions outliers{};
  SurfaceOptions surface{};
  /// Clean-up and self-check of the meshes (cleanAndSelfCheck); the CLI's defaults.
  SelfCheckOptions selfCheck = defaultSelfCheck();
  /// Before the self-check (duplex mode, not distributed): zero-level components that carry no input point
  /// and whose inside the winding number calls empty space are removed from the field's finest level and
  /// from the mesh (repairPhantoms; the CLI's --no-phantom-repair turns it off).
  bool repairPhantoms = true;
  PhantomRepairOptions phantomRepair{};
  /// Also the printable shell: the zero mesh and the mesh of the smallest inward offset (δ > 0, which the
  /// fit must have: else runPipeline throws InvalidArgument before reading) joined into one closed mesh,
  /// cut by shellOptions' drain holes in the field (duplex mode only). shellOptions.offset is ignored (the
  /// chosen δ is used) and so is minCavityFraction (the offset meshes' clean-up fraction is used).
  bool shell = false;
  ShellOptions shellOptions{};
  /// The memory budget of every stage (--max-memory): when its maxMemoryBytes is set it replaces those of
  /// meshSampling, fit, normals, denoiseOptions and surface.polygonize. The grid's estimate is checked before
  /// the fit, so that a grid too large for it is refused before minutes of fitting.
  ResourceLimits limits{};

  static SelfCheckOptions defaultSelfCheck() {
    SelfCheckOptions o;
    o.minAreaFraction = 0.0;
    // Slivers of the δ level where a part is almost exactly 2δ thick (eight_110k at δ = 0.05: 3 of 4
    // components, none in the exact offset; fandisk_50k at 0.025: 7 of 8; docs/fidelity.md); the zero
    // level keeps everything and the self-check flags what carries no input point.
    o.minOffsetAreaFraction = 0.001;
    return o;
  }
};

/// One extracted surface: the zero level (offset 0) or an offset surface.
struct PipelineSurface {
  std::size_t field = 0;  ///< index into PipelineResult::fields
  double iso = 0.0;       ///< the level of that field (δ in duplex mode, 0 in separate mode)
  double offset = 0.0;    ///< δ of the surface (0 for the zero level), input units
  Mesh mesh;              ///< after the clean-up (small components dropped) and finishSurfaces
  MeshTopology topology;
  /// Of the mesh as written: float32-degenerate faces and slivers (below 1°), as `check` counts them.
  TriangleQuality quality;
  MeshFinishReport finish;  ///< cleaning, simplification and the deviation from the level set

  /// A closed, oriented 2-manifold with no self-intersecting triangle pair left by the projection (the pairs
  /// its undo found and could not remove: finish.project.selfIntersectionsLeft), no triangle degenerate in
  /// float32 and slivers on at most CheckOptions' default share of the faces (what `check` asks of them).
  /// What `fit --strict` asks of every mesh it writes.
  bool sound() const noexcept;
  /// Slivers on more than CheckOptions' default share of the faces (what `check` refuses).
  bool tooManySlivers() const noexcept {
    return static_cast<double>(quality.slivers) > CheckOptions{}.maxSliverShare * static_cast<double>(quality.faces);
  }
};

/// The printable shell of a pipeline run (PipelineOptions::shell).
struct PipelineShell {
  std::size_t surface = 0;  ///< index into PipelineResult::surfaces of the inner surface (the offset)
  Mesh mesh;
  ShellReport report;
  std::string note;         ///< which offset was chosen when several are inward ("" when one)
};

struct PipelineReport {
  std::string input;           ///< the input path ("" for a PointSet input)
  PointReadReport read;        ///< for a PointSet input: points and normals only; for a mesh: the samples
  /// A mesh input: its format, and what sampleMeshCloud found and did (warnings included).
  std::optional<MeshSampleReport> mesh;
  MeshFormat meshFormat = MeshFormat::Auto;
  std::size_t duplicatesMerged = 0;
  OutlierReport outliers;              ///< far outliers of the input (rows of the input as read)
  std::size_t outliersRemoved = 0;     ///< with PipelineOptions::removeOutliers
  std::optional<NormalReport> normals;   ///< when estimated
  std::optional<BilateralReport> denoise;  ///< when denoised
  /// The input's noise (estimateNoise on the points as read, with the outlier test's k-d tree). A cloud
  /// that looks noisy is denoised (PipelineOptions::denoiseWhenNoisy) or, when that is off, gets a hint on
  /// the progress log (the field interpolates the noise).
  NoiseEstimate noise;
  /// The points were denoised because they looked noisy (denoiseWhenNoisy), not because `denoise` asked.
  bool denoisedForNoise = false;
  bool separate = false;
  bool sideTest = false;
  bool creaseTest = true;  ///< FitOptions::creaseTest (report.json "crease_test")
  /// The fit; in separate mode the zero level's fit with offsets, Edelta (each offset field's E0 at its
  /// own points) and secondsTotal of the whole baseline.
  FitReport fit;
  /// Separate mode only: the fits as fitSeparate reported them, the zero level's first.
  std::vector<FitReport> separateFits;
  std::vector<std::size_t> separateFittedPoints;  ///< points each separate fit used
  SelfCheckReport selfCheck;
  /// What the phantom repair found and did (candidates 0 when it did not run or found nothing).
  PhantomRepairReport phantomRepair;
  /// The first field's extraction: its grid, statistics, growths and boundary contact.
  GridSpec grid;
  PolygonizeStats gridStats;
  int boxGrowths = 0;
  bool touchesBoundary = false;
  /// The distributed fit's partition and per-rank figures (runDistributedPipeline only).
  std::optional<DistributedReport> distributed;
  /// The distributed fit's extraction over the ranks (runDistributedPipeline with more than one rank).
  std::optional<DistributedExtractionReport> distributedExtraction;
  double secondsRead = 0.0, secondsPolygonize = 0.0;
  double secondsFinish = 0.0;  ///< finishSurfaces on every mesh
  double secondsTotal = 0.0;  ///< the whole runPipeline call

  /// Every level's CG converged (or needed no iteration), over all fits.
  bool converged() const noexcept;
};

struct PipelineResult {
  std::vector<ImplicitField> fields;     ///< one (duplex) or 1 + offsets (separate, the zero level's first)
  std::vector<PipelineSurface> surfaces; ///< the zero level, then one per offset
  std::optional<PipelineShell> shell;    ///< with PipelineOptions::shell
  PipelineReport report;
};

/// Runs the pipeline on the cloud or mesh at `inputPath` (a cloud: PLY or XYZ, with normals unless
/// options.estimateNormals; a mesh: STL, OBJ or PLY with faces, sampled by sampleMeshCloud, whose warnings
/// go to the interrupter's message lines and the report). Progress lines, fit events and cancellation go through `interrupter`
/// (nullptr: none). @throws IoError (reading), InvalidArgument (bad options, unfittable cloud; the
/// message names the file; options.surface.finish is validated before any work), DeviceError, Cancelled.
PipelineResult runPipeline(const Device& device, const std::string& inputPath, const PipelineOptions& options = {},
                           Interrupter* interrupter = nullptr);
/// The same for points in memory (with normals unless options.estimateNormals).
PipelineResult runPipeline(const Device& device, const PointSet& points, const PipelineOptions& options = {},
                           Interrupter* interrupter = nullptr);

/// `duplexfit fit` over the ranks of `comm` (docs/method.md, "Distributed fit"): each rank reads its own
/// rows of the PLY cloud at `inputPath` (readPlyVertexRows), the points move to the owners of their Morton
/// ranges, fitDistributed fits the one field that every rank then holds, and rank 0 alone extracts the
/// meshes from it (the self-check's input points are a proxy: gathered cell centroids). The other ranks'
/// results carry the field and the report but no surfaces. Clouds only; --separate, --estimate-normals,
/// --denoise, --remove-outliers, --shell and --offset-correction are InvalidArgument (not distributed yet).
/// Outlier detection is skipped. @throws as runPipeline.
PipelineResult runDistributedPipeline(const Device& device, Communicator& comm, const std::string& inputPath,
                                      const PipelineOptions& options, const DistributedOptions& distributed,
                                      Interrupter* interrupter = nullptr);

/// Output names: meshes "zero.EXT", "offsetJ.EXT"; fields "field.dpxf", then (separate) "field_offsetJ.dpxf".
std::vector<std::string> pipelineMeshNames(const PipelineResult& result, const std::string& meshFormat = "ply");
std::vector<std::string> pipelineFieldNames(const PipelineResult& result);
/// The shell's output name, "shell.EXT" (written when result.shell is set).
std::string pipelineShellName(const std::string& meshFormat = "ply");

/// Writes report.json's content (the keys of the CLI's report, docs in README) to `out`. `writeSeconds`
/// goes to seconds.write and is added to seconds.total.
void writePipelineReport(std::ostream& out, const PipelineResult& result, const std::string& meshFormat = "ply",
                         double writeSeconds = 0.0);

/// Writes the meshes (meshFormat: "ply", "obj" or "stl"; the shell too), the fields and report.json into
/// `folder` and commits it. @throws InvalidArgument for another format, IoError.
void writePipelineOutputs(const PipelineResult& result, StagedFolder& folder, const std::string& meshFormat = "ply");
/// The same into the folder `outDir` (created when missing); nothing is left there on failure.
void writePipelineOutputs(const PipelineResult& result, const std::string& outDir,
                          const std::string& meshFormat = "ply");

/// `duplexfit mesh`'s job: the level set {f = iso} of a field, small components dropped, then cleaned,
/// simplified when asked and measured (options.finish, finishSurfaces).
struct MeshPipelineResult {
  Mesh mesh;
  MeshTopology topology;
  DroppedComponents dropped;
  MeshFinishReport finish;
  SurfaceResult extraction;  ///< grid and statistics (its meshes are moved out: empty)
};
/// The area fraction below which a re-extracted level drops components when the caller gives none, as the
/// fit treats its own meshes: 0 at iso 0 (everything kept), the fit's offset fraction (0.001,
/// PipelineOptions::defaultSelfCheck) at any other level, so that `mesh --iso D` gives the fit's offset mesh.
double defaultMinComponent(double iso);

/// @throws InvalidArgument (minComponent not in [0, 1), bad options, a simplification request without
/// meshoptimizer in the build: before any work), DeviceError, Cancelled.
MeshPipelineResult runMeshPipeline(const Device& device, const ImplicitField& field, double iso,
                                   const SurfaceOptions& options = {}, double minComponent = 0.0,
                                   Interrupter* interrupter = nullptr);

/// `duplexfit mesh --shell`'s job: the levels 0 and δ = options.offset of a saved field in one pass, small
/// components dropped as the fit does (minComponent on the zero mesh; the larger of it and the fit's default
/// offset fraction, 0.001, on the offset mesh and for the drained mesh's cavities), joined into the shell
/// (buildShell) or, with drain holes, the drained solid polygonized on the same grid (drainShell).
struct ShellPipelineResult {
  ShellResult shell;
  DroppedComponents droppedZero, droppedOffset;
  SurfaceResult extraction;  ///< grid and statistics of the levels' extraction (its meshes are moved out)
  std::string note;          ///< when δ is not one of the field's fitted offsets ("" otherwise)
};
/// @throws InvalidArgument (δ not > 0: the message names --iso; bad options), DeviceError, Cancelled.
ShellPipelineResult runShellPipeline(const Device& device, const ImplicitField& field, const ShellOptions& options,
                                     const SurfaceOptions& surface = {}, double minComponent = 0.0,
                                     Interrupter* interrupter = nullptr);

/// `duplexfit mesh --json`: the mesh's file, iso, topology, dropped components, grid and its finishing
/// report (cleaning, simplification, level-set deviation: the keys of report.json's "meshes" entries).
void writeMeshPipelineJson(std::ostream& out, const MeshPipelineResult& result, const std::string& outputPath,
                           double iso);
/// `duplexfit mesh --shell --json`: the shell's file, volumes, validity, drain holes and grid (the keys of
/// report.json's "shell").
void writeShellPipelineJson(std::ostream& out, const ShellPipelineResult& result, const std::string& outputPath);

}  // namespace duplexfit
