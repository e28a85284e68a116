// Extraction of a fitted field's level sets (the surface and every offset surface) as meshes: the field is
// sampled on the device over the whole enlarged box (docs/method.md §7) and polygonized in one pass.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "duplexfit/device.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "duplexfit/polygonize.hpp"

namespace duplexfit {

struct SurfaceOptions {
  /// Grid cell size in input units; 0: σ_M/2 (docs/method.md §7), kept between the cells of minResolution
  /// and maxResolution. The offsets do not enter: the triangle count follows the input, not δ.
  double cell = 0.0;
  /// Cells along the box's longest side; overrides `cell` when > 0.
  int resolution = 0;
  /// Upper bound on the automatic resolution (cells along the longest side).
  int maxResolution = 512;
  /// Lower bound on the automatic resolution: the cell is at most (largest side)/minResolution, for sparse
  /// clouds whose σ_M/2 would give a visibly faceted mesh.
  int minResolution = 128;
  Precision precision = Precision::Float;
  /// The pipelines refine thin cells 2 levels (PolygonizeOptions::refineLevels; `--refine-levels`).
  PolygonizeOptions polygonize = [] {
    PolygonizeOptions o;
    o.refineLevels = 2;
    return o;
  }();
  /// Unless polygonize.refineTolerance is set, the local refinement (PolygonizeOptions::refineLevels) keeps
  /// the thin cells whose contour is farther than this fraction of the field's largest side from the level
  /// set: half the level-set deviation the pipelines report against (0.1% of the side), the projection's
  /// target (narrower features are the neck pass's). 0: every thin cell.
  double refineTolerance = 5e-4;
  /// What the pipelines (runPipeline, runMeshPipeline) do with each mesh after extraction and the
  /// small-component drop: cleaning, optional simplification, the deviation from the level set
  /// (finishSurfaces). extractSurfaces itself returns the marching-tetrahedra meshes as they are.
  MeshFinishOptions finish{};
  /// The neck pass of the pipelines: where a finished mesh still lies farther than the deviation limit from
  /// its level set (a neck or fin of the level set narrower than a quarter cell, which two levels of local
  /// refinement cannot follow), that level set is extracted again with the grid cells there and around them
  /// refined one level more (PolygonizeOptions::refineDeeperCells), finished again, and the new mesh is
  /// kept when it is closer to the level set and still closed. It costs one more extraction and finish of
  /// that level set, so it runs only on meshes of at most this many faces (0: never; `--no-neck-pass`).
  std::size_t neckPassMaxFaces = 2000000;
  /// ... and only where the points beyond the limit lie within at most this many cells (with the 2 cells
  /// around each): a neck is local, while a level set off by more than the limit along whole edges (a CAD
  /// part's creases, where the field's level set itself is rounded) would refine thousands of cells for
  /// little gain (fandisk_50k: 3,439 and 9,575 cells, 6 s of fit became 189 s, the offset still 0.66% off).
  /// 2,000 since the refinement as deep as the contour needs (2026-12-06): cells refined one level may sit
  /// up to the refinement tolerance, so a neck's points beyond the limit span more cells (the bunny twin's
  /// offset 1,605 in 6 clusters, maxplanck_12k's at δ = 0.025 1,591 in 5), while the crease cases measured
  /// span 2,460 and more (docs/method.md §7).
  std::size_t neckPassMaxCells = 2000;
  /// The neck pass first replaces only the faces around its cells (the level set extracted again in boxes
  /// around them, the patch finished on its own and joined by a band); when that is refused (the boundaries
  /// do not pair up, the result is not closed, crosses itself or is not closer) it extracts and finishes the
  /// whole level set again.
  bool localNeckPass = true;
};

/// The grid used for a field: its input bounds enlarged by the largest outward offset, 5% of the largest
/// side and three cells, with the cell size from the options. extractSurfaces grows it further when a
/// level set still reaches its boundary.
GridSpec surfaceGrid(const ImplicitField& field, const std::vector<double>& isoValues,
                     const SurfaceOptions& options = {});
/// The same for a field not fitted yet: its input bounds and finest support σ_M in input units
/// (fitScales(...).sigmaFinest), for estimates before the fit.
GridSpec surfaceGrid(const Eigen::AlignedBox3d& bounds, double sigmaFinest, const std::vector<double>& isoValues,
                     const SurfaceOptions& options = {});

struct SurfaceResult {
  std::vector<Mesh> meshes;  ///< one per iso value, in the order given
  GridSpec grid;             ///< the grid finally used
  PolygonizeStats stats;     ///< of the final extraction
  int boxGrowths = 0;        ///< times the box was enlarged because a level set reached its boundary
  bool touchesBoundary = false;  ///< still reaching the boundary after the last growth (mesh open there)
};

/// The polygonize options extractSurfaces uses for `field`: options.polygonize, with the refinement tolerance
/// taken from options.refineTolerance (a fraction of the field's largest side) unless set there.
PolygonizeOptions surfacePolygonizeOptions(const ImplicitField& field, const SurfaceOptions& options);

/// The field's values through an evaluator, as polygonize samples them.
FieldSampler valueSampler(const FieldEvaluator& evaluator);

/// Where level-set meshes touch the grid's box, per side (x, y, z low, then high: 1 = touched), and the box
/// grown by a tenth of its largest side on the touched sides, same cell size (extractSurfaces grows the grid
/// so that no level set is cut open by it).
std::array<double, 6> boundaryContacts(const std::vector<Mesh>& meshes, const GridSpec& grid);
GridSpec grownGrid(const GridSpec& grid, const std::array<double, 6>& contacts);

class Communicator;

/// One rank's share of a distributed extraction (extractSurfacesDistributed).
struct SlabExtractionReport {
  int rank = 0;
  int slabBegin = 0, slabEnd = 0;       ///< its cells along z, [begin, end) (empty: no cells)
  std::int64_t evaluatedNodes = 0;      ///< grid nodes it sampled (its slab and halo)
  std::int64_t refinedCells = 0;        ///< cells it contoured on refined tetrahedra (with its halo's)
  std::int64_t triangles = 0;           ///< of all its meshes
  std::uint64_t bytesSent = 0;          ///< its meshes sent to rank 0
  double seconds = 0.0;                 ///< its polygonize calls
};

/// The distributed extraction: per rank (on every rank), and rank 0's welding.
struct DistributedExtractionReport {
  std::vector<SlabExtractionReport> ranks;
  double weldSeconds = 0.0;
};

/// extractSurfaces over the ranks of comm, the same grid on every rank: rank r polygonizes the cells of
/// slab r along z (PolygonizeOptions::slabBegin; cuts at equal shares of the finest level's centres, so of
/// the surface), rank 0 receives every slab's meshes and welds them by vertex key (weldByKeys) into the
/// meshes extractSurfaces gives, up to the order of vertices and faces. Only rank 0's result has meshes;
/// every rank has the grid and the summed statistics. A level set reaching the box grows it on every
/// rank. Collective: every rank must call it.
SurfaceResult extractSurfacesDistributed(Communicator& comm, const FieldEvaluator& evaluator, const ImplicitField& field,
                                         const std::vector<double>& isoValues, const SurfaceOptions& options = {},
                                         Interrupter* interrupter = nullptr,
                                         DistributedExtractionReport* report = nullptr);

/// The slab cuts of extractSurfacesDistributed: `parts` + 1 cell indices along z from 0 to grid.cells(2),
/// non-decreasing, at equal shares of the finest level's centres (an empty slab where the cells are fewer
/// than the parts).
std::vector<int> slabCuts(const ImplicitField& field, const GridSpec& grid, int parts);

/// Meshes of {f = iso} for every iso value, in input coordinates, outward oriented (normals toward
/// decreasing f). @throws InvalidArgument (empty iso list, bad options), DeviceError, Cancelled.
SurfaceResult extractSurfaces(const Device& device, const ImplicitField& field, const std::vector<double>& isoValues,
                              const SurfaceOptions& options = {}, Interrupter* interrupter = nullptr);

/// The same with an evaluator already built for `field` (FitResult::evaluator: no second upload); its
/// device and precision are used, options.precision is ignored.
SurfaceResult extractSurfaces(const FieldEvaluator& evaluator, const ImplicitField& field,
                              const std::vector<double>& isoValues, const SurfaceOptions& options = {},
                              Interrupter* interrupter = nullptr);

}  // namespace duplexfit
