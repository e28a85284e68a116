// Polygonisation of level sets of a scalar field over a regular grid (docs: docs/method.md §7,
// §12.15): marching tetrahedra on a Kuhn (Freudenthal) triangulation of the grid, with node values
// sampled in large batches through a callback and, optionally, only near the requested level sets.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "duplexfit/interrupter.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/resources.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

/// Evaluates the field at #Q query points: fills values (resized by the callee to Q) with f(queries
/// row i). Called from the calling thread only, with batches of up to PolygonizeOptions::batchSize
/// points (whole coarse lattices, whole groups of refined blocks, or z-slabs of tiles).
using FieldSampler = std::function<void(const Points& queries, Eigen::VectorXd& values)>;

/// A regular grid of cells(0)×cells(1)×cells(2) box-shaped cells spanning box exactly; nodes are
/// numbered 0..cells(a) along each axis a, node i sits at box.min() + i·cellSize() (the last node
/// is box.max() exactly).
struct GridSpec {
  /// Upper bound on (cells(0)+1)(cells(1)+1)(cells(2)+1), about 1290³ nodes.
  static constexpr std::int64_t kMaxNodes = std::int64_t{1} << 31;

  Eigen::AlignedBox3d box;                          ///< model units
  Eigen::Vector3i cells = Eigen::Vector3i::Zero();  ///< cells per axis, each ≥ 1

  /// Cubic cells of edge `cell`: each axis gets ⌈extent/cell⌉ cells (at least one) and the box is
  /// grown symmetrically about its centre to exactly cells·cell, so the grid covers the input box.
  /// @throws InvalidArgument when cell is not finite and positive, the box is empty or not finite,
  ///         or the grid would exceed kMaxNodes.
  static GridSpec fromCellSize(const Eigen::AlignedBox3d& box, double cell);

  /// @throws InvalidArgument naming the field: a cell count < 1, a box corner that is not finite,
  ///         box.max() ≤ box.min() on an axis, or more than kMaxNodes nodes.
  void validate() const;

  /// Edge lengths of one cell, (box.max() − box.min()) / cells.
  Eigen::Vector3d cellSize() const;
  /// Number of nodes, the product of cells(a) + 1.
  std::int64_t nodeCount() const;
  /// Position of node (i, j, k), 0 ≤ i ≤ cells(0) etc. (no range check).
  Eigen::Vector3d node(int i, int j, int k) const;
};

/// How polygonize samples the field.
struct PolygonizeOptions {
  /// true: sample a coarse lattice, then refine only blocks that may contain a crossing (below);
  /// false: sample every node (reference mode for checks; 4 bytes of storage per node).
  bool adaptive = true;
  /// Assumed bound L on |∇f| over the box (f approximates a distance, so |∇f| ≈ 1; 2 is a safety
  /// factor). A block is skipped when, for every iso value c, all 8 corners lie on one side of c
  /// and the balls of radius |f(corner) − c| / L around the corners cover the block, i.e. some
  /// point m of the block has |m − corner| < |f(corner) − c| / L for all corners (tried: the
  /// centre, which gives the rule "every corner is farther than L × half the diagonal from c", and
  /// a point moved toward the corners nearest to c). Under |∇f| ≤ L no point of such a block
  /// reaches c. Where the field is steeper, a surface that crosses skipped blocks is still followed
  /// cell by cell and closed (PolygonizeStats::continuedCells > 0 tells), but a component lying
  /// wholly in skipped blocks is missed. Must be finite and > 0; use adaptive = false for arbitrary
  /// fields.
  double lipschitz = 2.0;
  /// Cells per coarse block edge: 2, 4, 8, 16, 32 or 64 (also the edge of the storage tiles, in
  /// nodes). Blocks that are not skipped are halved recursively (octree style, tested again at each
  /// level) down to blocks of 2 cells per edge; there each cell is tested against the balls of the
  /// block's corners before its nodes are sampled.
  int coarseStep = 8;
  /// Most points per sampler call (≥ 1). Sampling requests are gathered across many blocks up to
  /// this size.
  std::int64_t batchSize = std::int64_t{1} << 20;
  /// OpenMP threads for extraction; 0 = the OpenMP default. The output does not depend on it.
  int threads = 0;
  /// The memory budget: polygonize refuses a grid whose estimate (estimatePolygonize) exceeds it.
  ResourceLimits limits{};
  /// Local refinement where the grid is too coarse for the field: a crossed cell with a node whose
  /// neighbours on both sides along an axis lie on the other side of an iso value (a plate or gap about
  /// one node thick, which linear interpolation cannot follow: the contour bridges it or leaves holes)
  /// is contoured on tetrahedra refineLevels times halved (cells 2^refineLevels times smaller), and its
  /// neighbours within refineDilation cells one level less, by conforming bisection of their Kuhn
  /// tetrahedra; the closure brings in the cells needed to keep the mesh conforming, so the meshes stay
  /// watertight and their vertices on the unrefined edges are those of the plain extraction. Smooth
  /// surfaces have such layers too where they touch a grid line tangentially (a coarse sphere's poles):
  /// refineTolerance leaves the cells whose contour is already close. 0 (the default here): off; the
  /// pipelines' SurfaceOptions turn it on with 2 levels and a tolerance.
  int refineLevels = 0;
  bool refineThin = true;  ///< detect the cells above (false: only refineCells)
  /// > 0: of those cells, refine only where the contour is farther than this from the level set (the
  /// centre of a contour polygon has |f − iso| above it; model units, one evaluation per polygon). Along
  /// sharp edges such layers are common and the plain contour is close enough; in thin plates it is not.
  double refineTolerance = 0.0;
  int refineDilation = 1;
  /// With refineLevels ≥ 2 and a tolerance: the deviating cells are refined one level less first, and only
  /// those whose contour there is still beyond refineTolerance (the centre of a tetrahedron's contour
  /// polygon) or that still hold a layer one finer lattice point thick are refined refineLevels times, with
  /// their ring; the others stay one level less, with no ring (PolygonizeStats::shallowCells). false: every
  /// deviating cell refineLevels times.
  bool refineAsNeeded = true;
  /// Refined cells requested by the caller (refined like the detected ones).
  std::vector<std::array<int, 3>> refineCells;
  /// Cells refined one level more than refineLevels (at most 3 in all), their neighbours within
  /// refineDilation cells refineLevels times: where a feature is narrower than a quarter cell (a neck of an
  /// offset level set), as the pipelines' neck pass asks (SurfaceOptions::neckPass). Needs refineLevels ≥ 1.
  std::vector<std::array<int, 3>> refineDeeperCells;
  /// More seed and ring cells than this skip the refinement (PolygonizeStats::refinementSkipped):
  /// each refined cell costs about 8^refineLevels field evaluations.
  std::int64_t maxRefinedCells = std::int64_t{1} << 17;
  /// A slab of the grid for distributed extraction: contour only the cells with z index in
  /// [slabBegin, slabEnd) (slabEnd < 0: up to the last cell). The nodes are sampled over the slab plus
  /// slabHalo(options) cells on each side, so that the slab's triangles, vertices and refined cells are
  /// those of the whole grid's extraction there; PolygonizeResult::vertexKeys then names every vertex,
  /// and the slabs of one grid weld into the whole grid's meshes by weldByKeys. 0, −1: the whole grid.
  int slabBegin = 0;
  int slabEnd = -1;
  /// Fill PolygonizeResult::vertexKeys (always done for a slab).
  bool keepVertexKeys = false;
};

/// Cells sampled beyond each side of a slab (PolygonizeOptions::slabBegin): one or more whole blocks
/// of coarseStep cells, at least 8 cells, beyond the reach of the refinement's closure.
int slabHalo(const PolygonizeOptions& options);

/// What polygonize is expected to hold for a grid, before it samples anything.
struct PolygonizeEstimate {
  double nodes = 0.0;        ///< nodes of the grid
  double storedNodes = 0.0;  ///< node values expected in memory (tiles; all of them when not adaptive)
  double triangles = 0.0;    ///< triangles of all meshes
  double storeBytes = 0.0;   ///< node store: coarse lattice, tile tables, tiles and cell marks
  double meshBytes = 0.0;    ///< the meshes and, during extraction, the per-thread pieces and welding
  double bytes() const noexcept { return storeBytes + meshBytes; }
};

/// The estimate for `isoCount` level sets: in adaptive mode, the refined tiles are those a surface of
/// about the grid box's own area crosses per level set (twice that, for the neighbours refined with
/// them), and the triangles about four per boundary cell of the box per level set (marching tetrahedra
/// make about 8 a cell² of surface). A level set of much larger area (a sponge) can exceed it; a sphere filling the box uses about half of it.
PolygonizeEstimate estimatePolygonize(const GridSpec& grid, std::size_t isoCount, const PolygonizeOptions& options = {});

/// Throws MemoryLimitExceeded ("polygonize: the NXxNYxNZ grid ... needs about ...") when the estimate is over
/// options.limits; polygonize calls it before it allocates, the pipelines before the fit.
void checkPolygonizeMemory(const GridSpec& grid, std::size_t isoCount, const PolygonizeOptions& options);

/// What the sampling and extraction did.
struct PolygonizeStats {
  std::int64_t totalNodes = 0;      ///< nodes of the grid
  std::int64_t evaluatedNodes = 0;  ///< nodes passed to the sampler (each at most once)
  std::int64_t samplerCalls = 0;    ///< number of sampler invocations
  std::int64_t coarseBlocks = 0;    ///< coarse blocks (adaptive mode; 0 otherwise)
  std::int64_t refinedBlocks = 0;   ///< coarse blocks not skipped for every iso value
  /// Cells sampled to close surfaces that left the refined region: 0 unless |∇f| exceeded
  /// PolygonizeOptions::lipschitz somewhere (then consider a larger bound).
  std::int64_t continuedCells = 0;
  /// Chunks (layers of cells) of an extraction round taken as they were into the next round: those with no
  /// cell continued in or next to them.
  std::int64_t reusedChunks = 0;
  /// Extraction rounds: 1, plus one for each round of continued cells (a round whose open cells were all
  /// marked already, which a stale reused chunk would report, adds none and costs a full round more).
  std::int64_t extractionRounds = 0;
  std::int64_t storageBytes = 0;   ///< memory held by the sampled node values (tiles + lattice)
  std::int64_t thinCells = 0;          ///< crossed cells with a node layer one node thick
  std::int64_t deviatingCells = 0;     ///< of those, the ones beyond refineTolerance (all of them without it)
  /// of those, the ones refined one level less, with no ring: their contour there is within refineTolerance
  std::int64_t shallowCells = 0;
  std::int64_t refinedSeeds = 0;       ///< cells refined fully (the thin ones and their neighbours)
  std::int64_t refinedCells = 0;       ///< cells contoured on refined tetrahedra (seeds and closure)
  std::int64_t refinedTetrahedra = 0;  ///< their tetrahedra
  std::int64_t refinedEvaluations = 0; ///< field evaluations at the refined points
  bool refinementSkipped = false;      ///< more seeds than PolygonizeOptions::maxRefinedCells
  double refinedSeconds = 0.0;         ///< refined contouring, its evaluations included
  double samplingSeconds = 0.0;    ///< wall time of the sampling phase, sampler calls included
  double samplerSeconds = 0.0;     ///< wall time spent inside the sampler
  double extractionSeconds = 0.0;  ///< wall time of triangle extraction and welding
  double totalSeconds = 0.0;
  /// evaluatedNodes / totalNodes.
  double evaluatedFraction() const noexcept {
    return totalNodes > 0 ? static_cast<double>(evaluatedNodes) / static_cast<double>(totalNodes)
                          : 0.0;
  }
};

/// The meshes of polygonize, one per iso value in input order, with the run's statistics.
struct PolygonizeResult {
  std::vector<Mesh> meshes;
  PolygonizeStats stats;
  /// With PolygonizeOptions::keepVertexKeys or a slab: per mesh, each vertex's key, unique to the grid edge
  /// (or refined edge) it lies on, so equal keys in two slabs' meshes are the same vertex.
  std::vector<std::vector<std::uint64_t>> vertexKeys;
};

/// The slab meshes of one iso value (pieces[s] with its vertex keys keys[s]) as one mesh: vertices of equal
/// key are merged (the first piece's position is kept), in order of first appearance; faces in piece order.
/// @throws InvalidArgument when a piece's key count differs from its vertex count or a face index is out
///         of range.
Mesh weldByKeys(const std::vector<const Mesh*>& pieces, const std::vector<const std::vector<std::uint64_t>*>& keys);

/// Extracts the level sets {f = c} for every c in isoValues from one sampling pass.
///
/// Each cell is split into 6 tetrahedra around its main diagonal (min to max corner), so
/// neighbouring cells agree on face diagonals, and each tetrahedron is contoured by linear
/// interpolation. A node counts as inside when f(node) ≥ c (a symbolic perturbation: values exactly
/// equal to c never make ambiguous or degenerate topology), and a vertex is kept at least 64
/// single-precision ulps (of the grid's largest coordinate) away from both nodes of its edge, so
/// that a node value at or within rounding of c does not collapse the triangles around that node to
/// zero area, also once written in single precision. Each mesh is therefore watertight, 2-manifold and
/// consistently oriented with normals toward decreasing f (outward from {f > c}; positive
/// signedVolume), except where the surface reaches the grid boundary: it is left open there, so pad
/// the box by a few cells when closed meshes are needed. Vertices lie on grid edges (axis edges,
/// face and main diagonals of the tetrahedra), are shared by all incident triangles (welded by
/// edge), and are placed by linear interpolation of the node values; node values are stored in
/// single precision.
///
/// A cell is contoured only when all 8 of its nodes were sampled: in adaptive mode, the cells of
/// refined blocks plus every cell that a contoured surface enters through a face (so meshes stay
/// closed even where the Lipschitz assumption fails; see PolygonizeOptions::lipschitz). Under the
/// assumption the adaptive output is identical to the non-adaptive one. The output is
/// deterministic: vertices and faces are ordered by grid cell (z, then y, then x) and vertex ids by
/// first use, independent of the thread count, the batch size, the coarse step and the mode.
///
/// Memory: node values take 4 bytes per sampled node (tiles of coarseStep³ nodes), plus the meshes
/// and, during extraction, about as much again for per-thread mesh pieces.
///
/// @param sampler    the field (see FieldSampler); exceptions it throws propagate
/// @param grid       the grid, validated first
/// @param isoValues  the levels c, at least one, finite; duplicates give duplicate meshes
/// @param options    sampling options, validated first
/// @param interrupter optional; polled from the calling thread between batches and phases with the percent done
/// @throws MemoryLimitExceeded (an InvalidArgument) when estimatePolygonize exceeds options.limits;
///         InvalidArgument for a bad grid, option or iso list, for a sampler that returns the wrong
///         number of values, or for a non-finite value (naming the grid node and its position);
///         Cancelled when the interrupter interrupts.
PolygonizeResult polygonize(const FieldSampler& sampler, const GridSpec& grid,
                            const std::vector<double>& isoValues,
                            const PolygonizeOptions& options = {},
                            Interrupter* interrupter = nullptr);

}  // namespace duplexfit
