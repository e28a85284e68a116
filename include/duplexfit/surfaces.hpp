// Extraction of a fitted field's level sets (the surface and every offset surface) as meshes: the field is
// sampled on the device over the whole enlarged box (docs/method.md §7) and polygonized in one pass.
#pragma once

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
  /// set: a quarter of the level-set deviation the pipelines report against (0.1% of the side). 0: every
  /// thin cell.
  double refineTolerance = 2.5e-4;
  /// What the pipelines (runPipeline, runMeshPipeline) do with each mesh after extraction and the
  /// small-component drop: cleaning, optional simplification, the deviation from the level set
  /// (finishSurfaces). extractSurfaces itself returns the marching-tetrahedra meshes as they are.
  MeshFinishOptions finish{};
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
