// Duplex fitting (docs/method.md §1–§5, §8.1): an oriented point cloud in, ONE multi-level CSRBF field out
// whose 0-level set is the surface and whose δ-level sets are the requested offset surfaces.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/linalg.hpp"
#include "duplexfit/resources.hpp"
#include "duplexfit/point_set.hpp"

namespace duplexfit {

/// Preconditioner of the level solves.
enum class PreconditionerKind {
  Jacobi,       ///< the paper's choice; only a scaling here (constant diagonal 1 + λ_k)
  BlockJacobi,  ///< exact inverses of diagonal blocks of spatially ordered centres
  Fsai          ///< factorised sparse approximate inverse on each centre's strongest couplings (default)
};

/// Where each level's matrix Φ + λI is assembled (docs/method.md §5, "Assembly on the device"). Auto: on the
/// device when it is an OpenCL GPU or accelerator with double precision (the host's cores are then the
/// scarce resource), else on the host. Device: on any OpenCL device with double precision (the kernels'
/// geometry is double; elsewhere the host assembles). Both give the same matrix bit for bit.
enum class AssemblyPlace { Auto, Host, Device };


/// Fit parameters. Every field documents its unit and default; defaults follow docs/method.md.
struct FitOptions {
  /// Signed offsets δ in input units (or fractions of the bounding box's largest side when offsetsRelative):
  /// δ > 0 inward (hollowing), δ < 0 outward. Each must be non-zero and smaller than that largest side.
  std::vector<double> offsets;
  bool offsetsRelative = false;
  /// The input normals already point into the solid (otherwise they are flipped, docs/method.md §1).
  bool normalsInward = false;
  /// η of the offset validity test: keep q = p + δν when no other point is closer than |δ|(1 − η) (§3.1).
  double validityTolerance = 1e-2;
  /// M, the number of levels; 0: from σ_1/σ_0 (§4.6).
  int levels = 0;
  /// α in σ_1 = α·L (L the bounding-box diagonal, §4.4).
  double alpha = 0.75;
  /// s in λ_k = s·k (approximation mode for noisy data, §5); 0 interpolates.
  double smoothing = 0.0;
  /// ε_fit: stop before level k ≥ 2 when max |t_i − f_{k−1}(c_i)| ≤ ε_fit (normalised units); 0: off.
  double fitTolerance = 0.0;
  /// Centres of a level closer than mergeDistance·σ_k are merged (zero-level over offset over off-surface,
  /// §3.5). Near-duplicates make the level system ill-conditioned: on fandisk_550k (random sampling) the
  /// finest level needs 1896 CG iterations at the spec's 1e-6, 1323 at 1e-3 and 445 at 1e-2, while E_0
  /// stays below 1e-5 (|f| at a merged point ≲ mergeDistance·σ_k). Default 1e-2; 1e-6 is the spec's.
  double mergeDistance = 1e-2;
  /// Side test (ours, off by default): also reject an offset or off-surface point that lies behind the
  /// tangent plane of its nearest other input point. It removes spurious closed sheets planted outside the
  /// solid by normals that disagree with their neighbours' (maxplanck_40k, δ = 0.01: 2 → 1 components of
  /// the zero mesh, mean deviation of the offset from the exact one 3.1% → 0.65% of δ), but it can reject
  /// valid points at coarse levels where the curvature between cell centroids exceeds δ (torus_10k,
  /// δ = −0.05: max |f − δ| on the exact offset 7.4% → 14% of |δ|, over a sampling hole).
  bool sideTest = false;
  /// Crease-plane test (ours, docs/method.md §3.1, "Crease-plane test"): also reject an offset point or an
  /// offset's medial point (not an off-surface point) closer than half its step to the tangent plane of a
  /// sample across a convex sharp edge (within that sample's disc of 1.5 × its 8th-neighbour distance). The
  /// distance test sees only samples: where random sampling leaves a strip along an edge empty, it keeps
  /// companions that lie almost on the unsampled face and pulls the δ level onto the surface there
  /// (cube_24k, δ = 0.02: offset points 99% of δ off, a tube of genus 1 along an edge).
  bool creaseTest = true;
  /// Sign anchors (ours, docs/method.md "Sign of empty space"): at levels 1 … M − anchorSkipFinest (M − 1), centres
  /// on a σ_k/2 grid in empty space (3σ_k/4 … 2σ_k from the samples; level 1 everywhere in the enlarged box)
  /// with the signed distance to the cloud as target, the sign from the cloud's winding number. Keeps
  /// coarse levels from filling holes and cavities with phantom solid (thin_torus_20k: a blob in the hole).
  bool signAnchors = true;
  int anchorSkipFinest = 1;
  /// Overshoot check at the finest level (ours, docs/method.md "Overshoot between sparse samples"): after
  /// level M is solved, f is evaluated at p + s·D·ν for every input point on the off-surface side(s) s,
  /// D = overshootSpacings × the median sample spacing. Where f puts such a point less than D/2 on its side
  /// and no other input point lies within D of it (the space there is empty), the point becomes a
  /// constraint of level M with target s·D and the level is solved again (at most overshootRounds times).
  /// Lowers the bulbs and bridges that level M's bumps raise between sparse samples at sharp ridges and
  /// narrow gaps (maxplanck_40k: one handle more than the truth without it; wheel_29k: its worst bulb
  /// 0.021 → 0.017 above the truth). Not in the distributed fit.
  bool overshootCheck = true;
  double overshootSpacings = 1.5;
  int overshootRounds = 2;
  /// Medial constraints (ours, docs/method.md "Thin parts"): offset and off-surface candidates rejected by
  /// the validity test are moved back along their normal onto the medial surface (largest valid step) and
  /// kept with their true distance as target, instead of being dropped.
  bool medialConstraints = true;
  /// Offset correction (ours, docs/method.md "Offset correction"): after the hierarchy, companions are moved
  /// onto each fitted δ level by Newton steps, compared there with the distance to the samples (a soup of
  /// disks, one per point), and one extra level of support σ_c = min(σ_M, |δ|/2) is fitted to the
  /// difference; it never reaches the zero level. Skipped when σ_c < 2 sample spacings. Off by default:
  /// on eight_110k (δ = 0.05) it merges offset islands (5 → 3 components) but raises the mean deviation
  /// from the exact offset (0.58% → 0.78% of δ) and E_δ (9e-7 → 9e-4).
  bool offsetCorrection = false;
  /// Points with a zero normal: false keeps them as f = 0 constraints without companions (§3.3).
  bool dropZeroNormalPoints = false;
  /// Arithmetic of the device solves and field evaluations.
  Precision precision = Precision::Float;
  SolverOptions solver{};
  /// Each level's CG also stops once max_i |t_i − f_k(c_i)| ≤ levelTolerance (normalised units, i.e.
  /// fractions of the bounding box's largest side): the remaining fit error at every centre. 0: only the
  /// relative criterion of `solver`. The default keeps E_0 well below the float path's 1e-4 target.
  double levelTolerance = 1e-6;
  /// CG relative tolerance of the levels below the finest (1 … M − 1), whose remaining error the next
  /// level fits again (docs/method.md §5, "Coarse tolerance"); 0: solver.relativeTolerance, as the finest
  /// level. With block Jacobi, 1e-3 halved those levels' iterations with E_0 and the Metro figures unchanged
  /// to 3 digits; with FSAI (the default) they take 6–14 iterations even at 1e-5, and at 1e-3 their fields
  /// depend on the CG's path enough to leave a 27-vertex blob in notched_cube_24k's inward offset, so the
  /// default is 1e-5 (docs/method.md §5).
  double coarseTolerance = 1e-5;
  PreconditionerKind preconditioner = PreconditionerKind::Fsai;
  AssemblyPlace assembly = AssemblyPlace::Auto;
  int blockSize = 16;  ///< rows per block of the block Jacobi preconditioner
  /// The FSAI factor's pattern: couplings |a_ij| ≥ fsaiThreshold·√(a_ii a_jj) below the diagonal, at most
  /// fsaiMaxNeighbours a row (the strongest). 0.2 keeps about 4 a row on the shared clouds' levels.
  double fsaiThreshold = 0.2;
  int fsaiMaxNeighbours = 32;
  /// The memory budget: before the first level, the finest level's lower bound (every input point a centre
  /// with its offset and off-surface companions, one non-zero a row) is checked; before each level's
  /// assembly, its estimate (estimateLevelBytes with the sampled non-zero count). Over it: MemoryLimitExceeded.
  ResourceLimits limits{};
};

/// The memory one level's solve holds: the CSR matrix on the host and the device, the block Jacobi
/// preconditioner, the CG vectors and the level's centres, targets and weights.
double estimateLevelBytes(std::size_t centres, std::size_t nonZeros, const FitOptions& options = {});

/// One hierarchy level's counts, solver outcome and stage times.
struct LevelReport {
  int level = 0;                      ///< k, 1 = coarsest
  double sigma = 0.0;                 ///< σ_k, input units
  std::size_t surfacePoints = 0;      ///< |P^k|
  std::vector<std::size_t> offsetCandidates, offsetKept;  ///< per offset: candidates and valid points
  std::size_t offSurfaceCandidates = 0, offSurfaceKept = 0;
  std::vector<std::size_t> offsetMedial;  ///< per offset: rejected candidates kept on the medial surface
  std::size_t offSurfaceMedial = 0;       ///< off-surface candidates kept on the medial surface
  std::size_t anchorsInside = 0, anchorsOutside = 0;  ///< sign anchors added (FitOptions::signAnchors)
  std::size_t anchorsSkipped = 0;     ///< anchor candidates skipped: ambiguous sign, crowded, near an offset
  double anchorSpacing = 0.0;         ///< grid spacing of the anchors (σ_k/2, doubled while too many; input units)
  std::size_t mergedCentres = 0;      ///< centres dropped as duplicates (closer than mergeDistance·σ_k)
  std::size_t centres = 0;            ///< N_k after merging
  std::size_t nonZeros = 0;
  double maxResidualBefore = 0.0;     ///< max |t_i − f_{k−1}(c_i)| before the solve (input units)
  /// Finest level only (FitOptions::overshootCheck): constraints added where f overshot into empty space,
  /// the rounds that added some (each solves the level again), and the time of the checks and solves.
  std::size_t overshootSites = 0;
  int overshootRounds = 0;
  double secondsOvershoot = 0.0;
  SolveStats solve;
  double secondsConstraints = 0.0, secondsAssembly = 0.0, secondsSolve = 0.0, secondsResidual = 0.0;
};

/// The offset-correction level (FitOptions::offsetCorrection).
struct OffsetCorrectionReport {
  bool applied = false;
  double sigma = 0.0;           ///< σ_c, input units
  std::size_t points = 0;       ///< correction centres
  std::size_t nonZeros = 0;
  /// |distance − f| / |δ| at the correction points before the correction level (mean, max)
  double meanBefore = 0.0, maxBefore = 0.0;
  SolveStats solve;
  double seconds = 0.0;
};

/// The whole fit: parameters actually used, per-level reports, errors (§8.1) and totals.
/// The side of the surface that gets the off-surface points (docs/method.md §3.2): the side without offsets.
enum class OffSurfaceSide {
  Outside,  ///< inward offsets only
  Inside,   ///< outward offsets only
  None,     ///< offsets on both sides
  Both      ///< no offsets
};
/// "outside", "inside", "none (offsets on both sides)", "both sides (no offsets)" (report.json's words).
const char* offSurfaceSideName(OffSurfaceSide side) noexcept;
/// "fsai", "block-jacobi" or "jacobi": the spelling of the CLI's --preconditioner and the Python option.
const char* preconditionerKindName(PreconditionerKind kind) noexcept;
/// The inverse of preconditionerKindName ("block_jacobi" is accepted too).
/// @throws InvalidArgument naming the text for any other.
PreconditionerKind parsePreconditionerKind(const std::string& text);
/// "auto", "host" or "device": the spelling of the CLI's --assembly and the Python option.
const char* assemblyPlaceName(AssemblyPlace place) noexcept;
/// The inverse of assemblyPlaceName. @throws InvalidArgument naming the text for any other.
AssemblyPlace parseAssemblyPlace(const std::string& text);

struct FitReport {
  std::string device;
  std::string deviceTuning;  ///< Device::tuning().describe(): launch shape and field kernel (report.json "device_tuning")
  std::string precision;
  /// The level solves' preconditioner ("fsai (threshold 0.2, at most 32 couplings a row)",
  /// "block-jacobi-16" or "jacobi"; report.json "preconditioner").
  /// Distributed fits name the one of their gathered levels and say that the distributed levels use
  /// block Jacobi on each rank's rows.
  std::string preconditioner;
  /// Where the level matrices were assembled: "host" or "device" (report.json "assembly"); "host and
  /// device" when some levels fell back to the host (a grid table over its bound).
  std::string assembly = "host";
  std::size_t inputPoints = 0, duplicatesMerged = 0, zeroNormals = 0;
  std::vector<double> offsets;         ///< δ in input units
  OffSurfaceSide offSurfaceSide = OffSurfaceSide::Outside;  ///< where the off-surface points went
  double sigma0 = 0.0, sigma1 = 0.0;   ///< input units
  double smoothing = 0.0;              ///< FitOptions::smoothing as fitted (λ_k = s·k; 0: interpolation)
  int levels = 0;                      ///< M
  bool stoppedEarly = false;           ///< the ε_fit test ended the fit before level M
  std::vector<LevelReport> levelReports;
  /// max |f(p)| over the input points (input units); for points that are finest-level centres it comes
  /// from that level's final residual (coarser levels as evaluated in the fit's precision), the others
  /// (merged away, dropped) are evaluated on the device
  double e0 = 0.0;
  /// per offset: max |f(q) − δ| over the valid finest-level offset points (from the final residual, in
  /// double; 0 when the fit stopped early)
  std::vector<double> eDelta;
  OffsetCorrectionReport correction;
  double secondsHierarchy = 0.0, secondsTotal = 0.0;
  double secondsWinding = 0.0;         ///< building the winding-number tree for the sign anchors
};

struct FitResult {
  ImplicitField field;
  FitReport report;
  /// The evaluator the fit built (every level of `field`, on the fit's device and precision): pass it
  /// to extractSurfaces instead of uploading the field again. Null for results not made by fit().
  std::shared_ptr<const FieldEvaluator> evaluator;
};

/// The supports of the fit's levels for a cloud (docs/method.md §4), in the points' own units.
struct FitScales {
  double diagonal = 0.0;     ///< L: the diagonal of the (slightly enlarged) bounding box
  double sigma0 = 0.0;       ///< σ_0: 0.75 × the mean leaf diagonal of an adaptive octree (≤ 8 points a leaf)
  double sigma1 = 0.0;       ///< σ_1 = α·L, the coarsest support
  int levels = 0;            ///< M = max(1, ⌈log₂(2σ_1/σ_0)⌉), or the requested count
  double sigmaFinest = 0.0;  ///< σ_M = σ_1 / 2^(M−1)
};

/// The scales fit() uses for these positions with FitOptions::alpha = `alpha` and FitOptions::levels =
/// `levels` (0: automatic); the bilateral filter takes its area σ from here.
/// @throws InvalidArgument when there are no positions or one is not finite.
FitScales fitScales(const Points& positions, double alpha = 0.75, int levels = 0);

/// Fits the field. Points are used as given (merge duplicates first, e.g. PointSet::mergeDuplicates).
/// `interrupter` (may be null) receives a FitEvent at every stage of every level and at every
/// solver.progressInterval-th CG iteration, each followed by wasInterrupted(percent): the share of the
/// fit's work done (a level weighs as its centres, the levels ahead estimated; within a solve, the decades
/// of the residual gained), never decreasing, 100 at the final errors; -1 before the first level.
/// @throws InvalidArgument (too few/degenerate points, bad options naming the field), DeviceError, Cancelled.
FitResult fit(const Device& device, const PointSet& points, const FitOptions& options = {},
              Interrupter* interrupter = nullptr);

/// The separate-fit baseline (the comparison of the paper's Table 1, docs/method.md §11): the surface fitted
/// from the cloud alone and every offset surface from its own offset points alone, each a multi-level CSRBF
/// fit of its own (off-surface points on both sides, no offsets), so each field's 0-level is its surface.
struct SeparateFitResult {
  ImplicitField zero;                        ///< 0-level: the surface
  FitReport zeroReport;
  std::vector<ImplicitField> offsets;        ///< per offset δ_j: 0-level = the offset surface
  std::vector<FitReport> offsetReports;
  std::vector<double> offsetDeltas;          ///< δ_j in input units
  std::vector<std::size_t> offsetPoints;     ///< valid offset points fitted for δ_j
  double secondsTotal = 0.0;
};

/// The offset cloud of δ (input units, > 0 inward): q = p + δν (ν the inward unit normal) for every point
/// with a non-zero normal whose q passes the validity test of §3.1 with tolerance `eta`, with p's
/// (outward-facing, as given unless `normalsInward`) normal; `sideTest` as FitOptions::sideTest. @throws InvalidArgument for δ = 0 or
/// an empty result.
PointSet offsetPointCloud(const PointSet& points, double delta, bool normalsInward = false, double eta = 1e-2,
                          bool sideTest = false);

/// Runs the separate-fit baseline with the options of fit() (offsets as in fit(); a FitStage::Start event
/// with the message "surface" or "offset j" begins each fit). @throws as fit().
SeparateFitResult fitSeparate(const Device& device, const PointSet& points, const FitOptions& options = {},
                              Interrupter* interrupter = nullptr);

}  // namespace duplexfit
