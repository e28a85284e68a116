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
#pragma once

#include <cstddef>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/point_set.hpp"
#include "duplexfit/preprocess.hpp"
#include "duplexfit/self_check.hpp"
#include "duplexfit/surfaces.hpp"

namespace duplexfit {

struct PipelineOptions {
  /// The fit (offsets, levels, solver, ...). Its precision is used by every stage (normals, denoise,
  /// surfaces): the precision fields of the other options are ignored.
  FitOptions fit{};
  /// The separate-fit baseline (fitSeparate): one field per surface instead of one duplex field.
  bool separate = false;
  /// Estimate the normals (estimateNormals) instead of reading them; the input then needs none.
  bool estimateNormals = false;
  NormalOptions normals{};
  /// Bilateral point filter (bilateralFilter) after the normals, before the fit. The fit's smoothing is
  /// not changed: the CLI's --denoise also defaults --smoothing to 0.2.
  bool denoise = false;
  BilateralOptions denoiseOptions{};
  SurfaceOptions surface{};
  /// Clean-up and self-check of the meshes (cleanAndSelfCheck); the CLI's defaults.
  SelfCheckOptions selfCheck = defaultSelfCheck();

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
  Mesh mesh;              ///< after the clean-up (small components dropped)
  MeshTopology topology;
};

struct PipelineReport {
  std::string input;           ///< the input path ("" for a PointSet input)
  PointReadReport read;        ///< for a PointSet input: points and normals only
  std::size_t duplicatesMerged = 0;
  std::optional<NormalReport> normals;   ///< when estimated
  std::optional<BilateralReport> denoise;  ///< when denoised
  bool separate = false;
  bool sideTest = false;
  /// The fit; in separate mode the zero level's fit with offsets, Edelta (each offset field's E0 at its
  /// own points) and secondsTotal of the whole baseline.
  FitReport fit;
  /// Separate mode only: the fits as fitSeparate reported them, the zero level's first.
  std::vector<FitReport> separateFits;
  std::vector<std::size_t> separateFittedPoints;  ///< points each separate fit used
  SelfCheckReport selfCheck;
  /// The first field's extraction: its grid, statistics, growths and boundary contact.
  GridSpec grid;
  PolygonizeStats gridStats;
  int boxGrowths = 0;
  bool touchesBoundary = false;
  double secondsRead = 0.0, secondsPolygonize = 0.0;
  double secondsTotal = 0.0;  ///< the whole runPipeline call

  /// Every level's CG converged (or needed no iteration), over all fits.
  bool converged() const noexcept;
};

struct PipelineResult {
  std::vector<ImplicitField> fields;     ///< one (duplex) or 1 + offsets (separate, the zero level's first)
  std::vector<PipelineSurface> surfaces; ///< the zero level, then one per offset
  PipelineReport report;
};

/// Runs the pipeline on the cloud at `inputPath` (PLY or XYZ; it needs normals unless
/// options.estimateNormals). Progress lines, fit events and cancellation go through `interrupter`
/// (nullptr: none). @throws IoError (reading), InvalidArgument (bad options, unfittable cloud; the
/// message names the file), DeviceError, Cancelled.
PipelineResult runPipeline(const Device& device, const std::string& inputPath, const PipelineOptions& options = {},
                           Interrupter* interrupter = nullptr);
/// The same for points in memory (with normals unless options.estimateNormals).
PipelineResult runPipeline(const Device& device, const PointSet& points, const PipelineOptions& options = {},
                           Interrupter* interrupter = nullptr);

/// Output names: meshes "zero.EXT", "offsetJ.EXT"; fields "field.dpxf", then (separate) "field_offsetJ.dpxf".
std::vector<std::string> pipelineMeshNames(const PipelineResult& result, const std::string& meshFormat = "ply");
std::vector<std::string> pipelineFieldNames(const PipelineResult& result);

/// Writes report.json's content (the keys of the CLI's report, docs in README) to `out`. `writeSeconds`
/// goes to seconds.write and is added to seconds.total.
void writePipelineReport(std::ostream& out, const PipelineResult& result, const std::string& meshFormat = "ply",
                         double writeSeconds = 0.0);

/// Writes the meshes (meshFormat: "ply", "obj" or "stl"), the fields and report.json into `folder` and
/// commits it. @throws InvalidArgument for another format, IoError.
void writePipelineOutputs(const PipelineResult& result, StagedFolder& folder, const std::string& meshFormat = "ply");
/// The same into the folder `outDir` (created when missing); nothing is left there on failure.
void writePipelineOutputs(const PipelineResult& result, const std::string& outDir,
                          const std::string& meshFormat = "ply");

/// `duplexfit mesh`'s job: the level set {f = iso} of a field, small components dropped.
struct MeshPipelineResult {
  Mesh mesh;
  MeshTopology topology;
  DroppedComponents dropped;
  SurfaceResult extraction;  ///< grid and statistics (its meshes are moved out: empty)
};
/// @throws InvalidArgument (minComponent not in [0, 1), bad options), DeviceError, Cancelled.
MeshPipelineResult runMeshPipeline(const Device& device, const ImplicitField& field, double iso,
                                   const SurfaceOptions& options = {}, double minComponent = 0.0,
                                   Interrupter* interrupter = nullptr);

}  // namespace duplexfit
