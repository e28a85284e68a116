// Slicing a field for layered manufacturing (docs/method.md §10): per layer, the plane's samples of f are
// contoured by marching squares at the 0-level (and at an offset level in shell mode), the vertices are
// refined onto the true level set, joined into closed, oriented and nested loops, and the next layer's
// thickness follows from the cusp height τ and the vertical normal curvature (§10.2–§10.5). Also: the
// Common Layer Interface (CLI) file format, SVG pictures and raster masks of the layers.
#pragma once

#include <cstddef>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "duplexfit/interrupter.hpp"
#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/image.hpp"
#include "duplexfit/types.hpp"
#include "duplexfit/resources.hpp"

namespace duplexfit {

/// 2D points (plane coordinates), one per row.
using Points2 = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;

/// What a layer's region is. f > 0 inside the solid (docs/method.md §1).
enum class SliceMode {
  Zero,  ///< the solid {f ≥ 0}: loops at the 0-level only ("zero only" in §10.5)
  Shell  ///< the shell between the 0-level and the offset δ: {0 ≤ f ≤ δ} for δ > 0 (inward, hollowing),
         ///< {δ ≤ f ≤ 0} for δ < 0 (outward); thickness over both levels' contours ("hollowed")
};

/// How a vertex is classified convex/concave in the thickness formula (§10.4).
///
/// The paper's rule takes the sign of κ_v alone. On faces that point downward (the centre of curvature
/// above the point: the roof of a hole, the underside of a bulge) the wall extruded upward from the
/// layer's bottom contour then deviates the other way: on the §10.6 upright torus the paper rule lets the
/// cusp reach 0.024 at τ = 0.01 (roof of the hole), while the geometric rule keeps every cusp within τ
/// (0.0100) for one more layer (68 instead of 67; 78 instead of 77 in shell mode). Hence the default.
enum class CuspRule {
  Geometric,  ///< by the side of the centre of curvature along the build direction (§10.4 option; default)
  Paper       ///< the sign of κ_v, with c = |n·axis| (the spec's paper-compatible rule)
};
/// "geometric" / "paper"; parseCuspRule throws InvalidArgument naming the text.
const char* cuspRuleName(CuspRule rule) noexcept;
CuspRule parseCuspRule(const std::string& text);

/// "zero" / "shell"; parseSliceMode throws InvalidArgument naming the text.
const char* sliceModeName(SliceMode mode) noexcept;
SliceMode parseSliceMode(const std::string& text);
/// "x", "y", "z" → 0, 1, 2 (also "0", "1", "2"); @throws InvalidArgument naming the text.
int parseAxis(const std::string& text);

/// Slicing parameters; lengths in the field's world units.
struct SliceOptions {
  SliceMode mode = SliceMode::Zero;
  /// The build direction: 0 = x, 1 = y, 2 = z. Plane coordinates (u, v) are (y, z), (z, x), (x, y)
  /// respectively, so u × v = +axis and "counter-clockwise" means as seen from +axis.
  int axis = 2;
  /// τ, the cusp height of adaptive slicing (> 0). Not needed with uniform slicing.
  double cusp = 0.0;
  /// t_min and t_max clamp the adaptive thickness; 0: τ/4 and 5τ (§10.5 choices).
  double minLayer = 0.0;
  double maxLayer = 0.0;
  /// > 0: uniform slicing with this layer thickness instead of adaptive slicing.
  double layer = 0.0;
  /// g, the plane's sampling step; 0: the box's largest side / 200.
  double grid = 0.0;
  /// Shell mode: which of the field's offsets bounds the shell.
  int offsetIndex = 0;
  CuspRule rule = CuspRule::Geometric;
  /// Arithmetic of the device evaluations.
  Precision precision = Precision::Float;
  /// Root-finding steps (Illinois regula falsi on the true f along the cell edge) per contour vertex.
  int refineSteps = 4;
  /// Most plane samples (and vertices) evaluated in one batch; a finer grid is processed in bands of rows.
  std::size_t batchPoints = std::size_t{1} << 18;
  /// Plans with more layers (height range / minimum or uniform layer) are refused before any work.
  std::size_t maxLayers = 1000000;
  /// A grid step that gives one layer more plane samples than this is refused (2^28: about 2 GB of samples).
  std::size_t maxPlaneSamples = std::size_t{1} << 28;
  /// The memory budget, checked before any sampling: one layer's plane samples and every layer's contours
  /// (estimateSliceBytes); the slice job adds its PNG masks or SL1 images.
  ResourceLimits limits{};
  /// First and last slicing heights along the axis; NaN: the box's minimum + 10⁻⁶·diagonal and its
  /// maximum (widened by |δ| for an outward shell). Layers are cut at heights < end.
  double start = std::numeric_limits<double>::quiet_NaN();
  double end = std::numeric_limits<double>::quiet_NaN();
};

/// One closed contour: vertices in plane coordinates, the closing edge implied (no repeated point).
struct SliceLoop {
  Points2 points;
  double level = 0.0;  ///< the iso-value of f the loop lies on
  double area = 0.0;   ///< signed area: > 0 counter-clockwise (an outer boundary), < 0 clockwise (a hole)
  int parent = -1;     ///< index (in the layer's loops) of the innermost loop that encloses this one, or −1
  int depth = 0;       ///< number of enclosing loops; even for outer loops, odd for holes
  bool outer() const noexcept { return area > 0.0; }
};

/// One layer: the plane at `height` along the axis and the region's boundary there. Loops are ordered
/// depth first (each outer loop followed by the loops it encloses), each starting at its lowest (u, v)
/// vertex; the region is on the left of every loop.
struct SliceLayer {
  double height = 0.0;
  /// The layer's thickness (distance to the next plane); adaptive: clamp(rawThickness, t_min, t_max).
  double thickness = 0.0;
  /// Adaptive: the minimum cusp thickness over the contour vertices before clamping (∞ without contours).
  double rawThickness = std::numeric_limits<double>::infinity();
  std::vector<SliceLoop> loops;
  double area = 0.0;              ///< the region's area: Σ signed loop areas
  bool touchesBoundary = false;   ///< a level set reached the padded grid's border even after growing it
  std::size_t vertexCount() const noexcept;
};

/// The slicing of a whole part, with the parameters actually used and counters.
struct SliceResult {
  std::vector<SliceLayer> layers;
  SliceMode mode = SliceMode::Zero;
  int axis = 2;
  bool adaptive = true;
  CuspRule rule = CuspRule::Geometric;
  double cusp = 0.0, minLayer = 0.0, maxLayer = 0.0, layer = 0.0, grid = 0.0;
  std::vector<double> levels;          ///< iso-values contoured: {0} or {0, δ}
  Eigen::AlignedBox3d bounds;          ///< the sliced box (world units)
  double start = 0.0, end = 0.0;       ///< first height and the stop height
  std::size_t samples = 0;             ///< field evaluations on the planes
  std::size_t refineEvaluations = 0;   ///< field evaluations refining vertices
  std::size_t vertices = 0;            ///< contour vertices in all layers
  double seconds = 0.0;
  std::size_t vertexCount() const noexcept { return vertices; }
};

/// Any function to slice: values (and ∇f, Hessians when asked) at #Q×3 world points, > 0 inside.
using FieldFunction = std::function<FieldSamples(const Points& queries, FieldDerivatives derivatives)>;

/// Plane coordinates (u, v) of a world point for the axis, and the world point of (u, v) at a height.
Eigen::Vector2d planeCoordinates(const Eigen::Vector3d& x, int axis);
Eigen::Vector3d worldPoint(const Eigen::Vector2d& uv, double height, int axis);

/// The §10.4 layer thickness for cusp height τ at a surface point with vertical normal curvature κ_v
/// (κ_v < 0 convex) and c = |cos θ| (paper rule; for CuspRule::Geometric pass the signed u_z as c and
/// κ_v); t_max when the cusp never reaches τ.
double cuspThickness(double kappaV, double c, double tau, double tMax, CuspRule rule = CuspRule::Paper);

/// The thickness of §10.3–§10.4 at one point from ∇f and the Hessian (6 values xx, xy, xz, yy, yz, zz).
double vertexThickness(const Eigen::Vector3d& gradient, const Eigen::Matrix<double, 1, 6>& hessian, int axis,
                       double tau, double tMax, CuspRule rule = CuspRule::Geometric);

/// Slices a field or a function. One evaluator is built per Slicer, so cutting many layers is cheap.
class Slicer {
 public:
  /// Slices `field` on `device` (batched FieldEvaluator calls).
  /// @throws InvalidArgument for bad options (naming the option), DeviceError.
  Slicer(const Device& device, const ImplicitField& field, const SliceOptions& options);
  /// Slices an arbitrary function over `bounds` (the part's box); `offsets` as ImplicitField::offsets().
  Slicer(FieldFunction function, const Eigen::AlignedBox3d& bounds, std::vector<double> offsets,
         const SliceOptions& options);
  Slicer(Slicer&&) noexcept;
  Slicer& operator=(Slicer&&) noexcept;
  ~Slicer();

  /// The contours at one height, with the thickness the layer would get there.
  SliceLayer layerAt(double height) const;
  /// Every layer from start to end (§10.5 stepping, or uniform). After each layer the interrupter (may be
  /// null) gets one message line ("  layer 12  height … thickness … loops …  (40%)") and is polled with
  /// the percent of the height range done. @throws Cancelled when it interrupts.
  SliceResult run(Interrupter* interrupter = nullptr) const;
  /// The options with defaults resolved (grid, t_min, t_max, start, end).
  const SliceOptions& options() const noexcept;
  /// The iso-values contoured.
  const std::vector<double>& levels() const noexcept;
  /// The sliced box.
  const Eigen::AlignedBox3d& bounds() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Slicer(device, field, options).run(interrupter).
SliceResult slice(const Device& device, const ImplicitField& field, const SliceOptions& options,
                  Interrupter* interrupter = nullptr);

// ---- Placement on the build plate -----------------------------------------------------------------

/// Where the layers go in the output files. Output coordinates (x, y, z) are the plane's (u, v) and the
/// height along the build axis, in output units: output = scale · model + translation.
enum class SlicePlace {
  Plate,  ///< the lowest layer's bottom at z = 0 and the part's (u, v) extent centred on the plate [0, W] × [0, D]
  None    ///< model coordinates (times the scale)
};
/// "plate" / "none"; parseSlicePlace throws InvalidArgument naming the text.
const char* slicePlaceName(SlicePlace place) noexcept;
SlicePlace parseSlicePlace(const std::string& text);
/// Millimetres per unit of "mm", "in", "um" (the CLI's $$UNITS); @throws InvalidArgument naming the text.
double lengthUnitMillimetres(const std::string& name);
/// "WxD" (also "W,D"; both > 0) as a plate size. @throws InvalidArgument naming the text.
Eigen::Vector2d parsePlateSize(const std::string& text);

struct PlacementOptions {
  SlicePlace place = SlicePlace::Plate;
  double scale = 1.0;  ///< output units per model unit (> 0)
  /// The plate's size W × D in output units (Plate only); zero: the part's (u, v) extent plus a margin of
  /// 2 grid steps on each side, rounded up to whole multiples of `plateStep` when that is > 0.
  Eigen::Vector2d plate = Eigen::Vector2d::Zero();
  double plateStep = 0.0;
};

/// A placement: output = scale · model + translation, per output axis (x, y, z) = (u, v, build axis).
struct SlicePlacement {
  SlicePlace place = SlicePlace::Plate;
  double scale = 1.0;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  ///< output units
  /// The build area in output coordinates: [0, W] × [0, D] (Plate); None: the sliced box's plane box
  /// (planeBox) scaled, grown to hold the part.
  Eigen::AlignedBox2d plate;
  bool plateGiven = false;     ///< the plate's size came from the options
  Eigen::AlignedBox3d part;    ///< the part in output coordinates: the loops' (u, v) extent, first bottom to last top
  double lowestModel = 0.0;    ///< the lowest layer's bottom in model coordinates (the height that goes to z = 0)
};

/// The placement of a sliced part. @throws InvalidArgument for a scale ≤ 0, a bad plate size, a plate with
/// place None, or a part larger than the plate (the message gives both sizes).
SlicePlacement placeSlices(const SliceResult& result, const PlacementOptions& options);
/// The result in output coordinates: loops, heights, thicknesses, areas, grid, cusp and layer limits,
/// start/end, and bounds (set to placement.part, the part's box, in the (u, v, axis) slots). Levels stay
/// the field's values.
SliceResult applyPlacement(const SliceResult& result, const SlicePlacement& placement);

// ---- Common Layer Interface (ASCII) -------------------------------------------------------------

/// One $$POLYLINE: dir 0 = clockwise (internal), 1 = counter-clockwise (external), 2 = open.
struct CliPolyline {
  int id = 1;
  int dir = 1;
  Points2 points;  ///< in the file's coordinates times its units (mm), the closing repeat removed
  bool closed = true;
};
struct CliLayer {
  double height = 0.0;  ///< $$LAYER value times units: the layer's top (CLI 2.0: the upper boundary's z)
  double bottom = 0.0;  ///< the previous layer's top; 0 (the build plate) for the first layer
  double thickness() const noexcept { return height - bottom; }
  std::vector<CliPolyline> polylines;
};
struct CliFile {
  double units = 1.0;       ///< $$UNITS: millimetres per file unit
  int version = 0;          ///< $$VERSION (e.g. 200), 0 when absent
  long declaredLayers = -1; ///< $$LAYERS, −1 when absent
  std::vector<CliLayer> layers;
};

/// Writes an ASCII CLI file atomically: header ($$ASCII, $$UNITS, $$VERSION/200, $$LABEL, $$DIMENSION,
/// $$LAYERS), then per layer $$LAYER/top (height + thickness: CLI 2.0 gives a layer's upper boundary) and
/// one closed $$POLYLINE per loop (the layer's contour at its bottom; the first point repeated at the end,
/// dir from the orientation). The result's lengths are `resultUnits` millimetres each (1: millimetres);
/// coordinates are written as lengths · resultUnits / units, `units` being $$UNITS (mm per file unit), so
/// with resultUnits = units the numbers are the result's own. @throws InvalidArgument (units or
/// resultUnits ≤ 0), IoError naming the path.
void writeCli(const std::string& path, const SliceResult& result, double units = 1.0, double resultUnits = 1.0);
/// Reads an ASCII CLI file (coordinates and heights scaled to mm; a layer's bottom is the previous layer's
/// top, 0 for the first). @throws IoError naming the file and
/// line for a missing file, a binary file, a malformed command or a count that does not match.
CliFile readCli(const std::string& path);

// ---- Pictures -----------------------------------------------------------------------------------

/// An SVG with one group per layer (id "layer_00001", …), loops as even-odd filled paths; v points up.
/// `layerIndex` ≥ 0 writes only that layer. @throws IoError naming the path.
void writeSliceSvg(const std::string& path, const SliceResult& result, int layerIndex = -1);

/// A grey mask of one layer over `area` (plane coordinates) with square pixels of size `pixel`: 255 where a
/// pixel centre lies inside the region (even-odd rule over the loops), 0 elsewhere; row 0 at the top
/// (largest v), so pixel (0, 0)'s outer corner is (area.min u, area.max v). The image has
/// maskPixels(area, pixel) pixels. @throws InvalidArgument for pixel ≤ 0 or an image over 65536 pixels a side.
Image rasterizeLayer(const SliceLayer& layer, const Eigen::AlignedBox2d& area, double pixel);
/// Columns and rows of a mask: ⌈size/pixel⌉ per side, a size within 10⁻⁶ pixel of a whole number of
/// pixels counting as that number.
Eigen::Vector2d maskPixels(const Eigen::AlignedBox2d& area, double pixel);

/// The plane box (u, v) of a result's bounds.
Eigen::AlignedBox2d planeBox(const SliceResult& result);

}  // namespace duplexfit
