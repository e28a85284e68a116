// The jobs of the CLI commands other than fit and mesh (pipeline.hpp), as library calls: each runs the job
// and returns its result with its report, and companion functions write the job's JSON report (the CLI's
// --json output, keys as the CLI has always written them) and its output files (atomically or staged).
// Progress lines (what the CLI prints on stderr without --quiet) go to Interrupter::message.
//
//   measure A B / measure O --offset-of S   runDistanceJob / runOffsetJob, writeDistanceJson / writeOffsetJson
//   check MESH                              runCheckJob, writeCheckJson
//   denoise / normals                       runDenoiseJob / runNormalsJob, writeCloudOutput, write*Json
//   section FIELD                           prepareSectionJob, runSectionJob (writes the PNGs), writeSectionJson
//   slice FIELD                             SliceJob (runSliceJob), writeSliceOutputs, writeSliceJson
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "duplexfit/atomic_file.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/point_set.hpp"
#include "duplexfit/preprocess.hpp"
#include "duplexfit/section.hpp"
#include "duplexfit/shell.hpp"
#include "duplexfit/sl1.hpp"
#include "duplexfit/slice.hpp"

namespace duplexfit {

// ---- measure and check -------------------------------------------------------------------------------

/// A mesh read for measuring, with its validation.
struct MeasuredMesh {
  std::string path;
  Mesh mesh;
  MeshValidation validation;
};
/// Reads and validates the mesh at `path`; degenerate triangles are reported as one message line.
MeasuredMesh loadMeasuredMesh(const std::string& path, Interrupter* interrupter = nullptr);

/// `measure A B`: Metro distances between two meshes.
struct DistanceJobResult {
  MeasuredMesh a, b;
  MeasureOptions options;
  DistanceReport report;
  double seconds = 0.0;  ///< reading and measuring
};
/// Message "measured N samples in T s" at the end. @throws IoError, InvalidArgument.
DistanceJobResult runDistanceJob(const std::string& pathA, const std::string& pathB, const MeasureOptions& options = {},
                                 Interrupter* interrupter = nullptr);

/// `measure O --offset-of S --delta D`: accuracy of an offset mesh against its surface.
struct OffsetJobResult {
  MeasuredMesh offset, surface;
  double delta = 0.0;
  MeasureOptions options;
  OffsetReport report;
  double seconds = 0.0;
};
OffsetJobResult runOffsetJob(const std::string& offsetPath, const std::string& surfacePath, double delta,
                             const MeasureOptions& options = {}, Interrupter* interrupter = nullptr);

/// `check MESH`: topology, orientation, genus and self-intersections (no degenerate-triangle message).
struct CheckJobResult {
  MeasuredMesh mesh;
  MeshCheck check;
  double seconds = 0.0;
};
/// Message "checked in T s" at the end.
CheckJobResult runCheckJob(const std::string& path, const CheckOptions& options = {}, Interrupter* interrupter = nullptr);

/// The --json documents (one JSON object and a newline) and the text tables of the three jobs.
void writeDistanceJson(std::ostream& out, const DistanceJobResult& result);
void writeOffsetJson(std::ostream& out, const OffsetJobResult& result);
void writeCheckJson(std::ostream& out, const CheckJobResult& result);
void writeDistanceText(std::ostream& out, const DistanceJobResult& result);
void writeOffsetText(std::ostream& out, const OffsetJobResult& result);
void writeCheckText(std::ostream& out, const CheckJobResult& result);

// ---- denoise and normals -------------------------------------------------------------------------------

/// What both pre-processing jobs report besides their own report.
struct CloudJobInfo {
  std::string input;
  bool inputHadNormals = false;
  std::string deviceSpec, deviceName;
  Precision precision = Precision::Float;
  double secondsKernelBuild = 0.0, secondsRead = 0.0;
  double secondsTotal = 0.0;  ///< the whole job call
};

struct DenoiseJobResult {
  CloudJobInfo info;
  PointSet points;  ///< the filtered cloud
  BilateralReport report;
};
/// `denoise`: builds the kernels for options.precision (timed apart), reads the cloud at `inputPath` (it
/// needs normals) and filters it. @throws IoError, InvalidArgument (no normals, bad options), DeviceError.
DenoiseJobResult runDenoiseJob(const Device& device, const std::string& inputPath, const BilateralOptions& options = {},
                               Interrupter* interrupter = nullptr);

struct NormalsJobResult {
  CloudJobInfo info;
  PointSet points;  ///< the cloud with its new (or kept) normals
  NormalReport report;  ///< default when the input's normals were kept
  bool keptExisting = false;
  /// The share of the input's nonzero normals within 90 degrees of the estimate (−1: none to compare).
  double agreeingWithInput = -1.0;
};
/// `normals`: as runDenoiseJob, then estimates the normals (or keeps the input's when `keepExisting` and it
/// has some). @throws as runDenoiseJob; InvalidArgument messages name the input.
NormalsJobResult runNormalsJob(const Device& device, const std::string& inputPath, const NormalOptions& options = {},
                               bool keepExisting = false, Interrupter* interrupter = nullptr);

/// Writes a job's cloud as binary PLY with normals (atomically) and returns the seconds it took.
double writeCloudOutput(const std::string& path, const PointSet& points);
/// The --json summaries; `writeSeconds` goes to seconds.write and is added to seconds.total.
void writeDenoiseJson(std::ostream& out, const DenoiseJobResult& result, const std::string& outputPath,
                      double writeSeconds = 0.0);
void writeNormalsJson(std::ostream& out, const NormalsJobResult& result, const std::string& outputPath,
                      double writeSeconds = 0.0);

// ---- section -------------------------------------------------------------------------------------------

struct SectionJobOptions {
  SectionOptions section;        ///< its points are read from pointsPath
  std::optional<SectionPlane> plane;  ///< one plane; none: the three axis planes through the box centre
  std::string pointsPath;        ///< a cloud whose points near the plane are drawn ("" for none)
  std::string output;            ///< OUT.png, or a folder (existing, or ending in '/') for section_x.png, ...
};

/// A section job ready to run: the field, the planes, the output files, the points read.
struct SectionJob {
  std::string fieldPath;
  ImplicitField field;
  std::vector<SectionPlane> planes;
  std::vector<std::string> files;  ///< one per plane
  SectionOptions options;
  bool points = false;  ///< a cloud was given
  double secondsPrepare = 0.0;  ///< loading and checking (added to SectionJobResult::secondsTotal)
};
/// Loads the field and the points and checks every plane (validateSection), before any device work.
SectionJob prepareSectionJob(const std::string& fieldPath, const SectionJobOptions& options);
/// The three planes through the field's box centre, rounded to 1e-4 of the box's size.
std::vector<SectionPlane> sectionCentrePlanes(const ImplicitField& field);

struct SectionJobResult {
  std::vector<std::string> files;
  std::vector<SectionResult> sections;  ///< summaries only (their pixels and values are released)
  std::string deviceSpec, deviceName;
  Precision precision = Precision::Float;
  bool points = false;
  double secondsSetup = 0.0;  ///< building the field's evaluator
  double secondsTotal = 0.0;  ///< prepareSectionJob and runSectionJob
};
/// Renders every plane and writes its PNG under a temporary name; all are moved into place at the end
/// (a failure leaves none). Messages: the field, then one line per section.
SectionJobResult runSectionJob(const Device& device, const SectionJob& job, Interrupter* interrupter = nullptr);
/// The --json summary (and the blank line the CLI has always printed after it); `fieldPath` as given.
void writeSectionJson(std::ostream& out, const SectionJobResult& result, const std::string& fieldPath);

// ---- slice ---------------------------------------------------------------------------------------------

struct SliceJobOptions {
  SliceOptions slice;
  /// Where the outputs are placed (default: on the plate) and the scale to output units. The job sets
  /// placement.plateStep to maskPixel, so an automatic plate is a whole number of mask pixels.
  PlacementOptions placement;
  double units = 1.0;         ///< millimetres per output unit (the CLI file's $$UNITS)
  std::string unitsName = "mm";  ///< the output unit's name for the report ("mm", "in", "um")
  double maskPixel = 0.0;     ///< > 0: PNG masks of the whole plate with this pixel size (output units)
  bool svgPerLayer = false;   ///< svg/layer_00001.svg, ... instead of slices.svg
  /// Drain holes (shell.hpp; shell mode with an inward offset only): the layers are then the contours of
  /// the drained solid {g' ≥ 0}, g' = min(f, δ − f, hole distances), the function `fit --shell` meshes (one
  /// level, 0: the slices' levels are {0}).
  std::vector<DrainHole> drainHoles;
  /// Non-empty: also an SLA package (sl1.hpp, needs libzip) of this name in the output folder, a plain
  /// file name ending in .sl1 or .sl1s. It needs uniform layers, millimetres and plate placement; the plate
  /// is then the display (sl1Options.printer: displayWidth × displayHeight), which the part must fit.
  std::string sl1;
  Sl1Options sl1Options;  ///< its printer and exposure settings (hollow: set by the job from the mode)
};

/// Summary statistics of the layers.
struct SliceStats {
  double thicknessMin = 0.0, thicknessMean = 0.0, thicknessMax = 0.0;
  std::size_t loops = 0;
};
SliceStats sliceStats(const SliceResult& result);

struct SliceJobResult {
  std::string input;  ///< the field's path, for the report
  std::string deviceSpec;
  SliceJobOptions options;  ///< with the options the slicer used
  SliceResult slices;       ///< in model coordinates
  SlicePlacement placement;
  SliceResult placed;       ///< in output coordinates (applyPlacement): what the files hold
  std::size_t layersTouchingBorder = 0;
  double secondsSlice = 0.0;
  double secondsTotal = 0.0;  ///< from the SliceJob's construction to the end of run()
};

/// A slicing job: the constructor validates the options against the field (Slicer) and the mask size, so
/// that an output folder can be staged before run() does the work. `field` must outlive the job.
class SliceJob {
 public:
  /// @throws InvalidArgument (bad options, naming the CLI's options: "--png-xy ... gives masks larger than
  /// 65536 pixels a side", "--scale", "--units", "--plate", a part's box larger than the plate; with --sl1:
  /// no libzip in this build, adaptive layers, units other than mm, a part's box larger than the display or
  /// taller than the printer), DeviceError.
  SliceJob(const Device& device, const ImplicitField& field, const SliceJobOptions& options,
           std::string input = std::string());
  /// The options with every default resolved.
  const SliceOptions& options() const noexcept { return options_.slice; }
  /// Messages: what is sliced, one line per layer, a warning when a level set reached the grid border, the
  /// placement. @throws Cancelled when the interrupter says so; InvalidArgument when the sliced part does
  /// not fit on the given plate.
  SliceJobResult run(Interrupter* interrupter = nullptr) const;

 private:
  Slicer slicer_;
  SliceJobOptions options_;
  std::string input_, deviceSpec_;
  std::chrono::steady_clock::time_point start_;
};
SliceJobResult runSliceJob(const Device& device, const ImplicitField& field, const SliceJobOptions& options,
                           const std::string& input = std::string(), Interrupter* interrupter = nullptr);

/// The masks' raster: the plate at the mask pixel size. Pixel (0, 0)'s outer corner is `origin` (the
/// plate's min x, max y); columns go +x, rows go −y.
struct SliceMaskInfo {
  Eigen::AlignedBox2d area;   ///< output coordinates covered by the image (the plate, rounded up to pixels)
  Eigen::Vector2d origin = Eigen::Vector2d::Zero();
  double pixel = 0.0;         ///< output units
  int width = 0, height = 0;  ///< pixels
  std::uint32_t pixelsPerMetre = 0;  ///< the pHYs value (0: none written, out of PNG's range)
  double dpi = 0.0;
};
/// The raster of a job's masks (result.options.maskPixel > 0). @throws InvalidArgument for a raster over
/// 65536 pixels a side.
SliceMaskInfo sliceMaskInfo(const SliceJobResult& result);

/// What writing the slice outputs measured (mask areas go to the report).
struct SliceOutputs {
  std::vector<double> maskArea;  ///< per layer, when masks were written (output units²)
  std::optional<Sl1Summary> sl1; ///< the SLA package, when one was asked for
  double secondsWrite = 0.0;
  std::string report;            ///< slices.json's content
};
/// Writes slices.cli, slices.svg (or svg/), masks/, the SLA package and slices.json into `folder` and commits
/// it (all or nothing). @throws IoError, InvalidArgument (the SLA package: writeSl1).
SliceOutputs writeSliceOutputs(const SliceJobResult& result, StagedFolder& folder);
/// slices.json's content (also the --json output). seconds.total = result.secondsTotal + writeSeconds. The
/// slicer's parameters (cusp, grid, layer limits, start, end, levels) are in model units; the layers
/// (heights, bottom/top/thickness, areas) in output coordinates; "placement" maps one to the other and
/// "masks" (when maskArea is given) describes the raster, "sl1" (when `sl1` is given) the SLA package.
void writeSliceJson(std::ostream& out, const SliceJobResult& result, const std::vector<double>& maskArea = {},
                    double writeSeconds = 0.0, const Sl1Summary* sl1 = nullptr);

}  // namespace duplexfit
