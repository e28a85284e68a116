// The neck pass's local replacement (docs/method.md §7, "The neck pass"): the faces of a finished closed
// mesh in a zone of grid cells are replaced by a fresh extraction of the same level set there, finished on
// its own (cleaning and projection with its boundary held), and joined to the rest by a band of triangles
// between the two boundaries. Internal to the pipelines; spliceZone says why when it cannot splice, and the
// caller then re-finishes the whole mesh.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "duplexfit/mesh.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "duplexfit/polygonize.hpp"

namespace duplexfit::detail {

struct SpliceResult {
  bool ok = false;
  std::string why;  ///< when not ok: what stopped it
  Mesh mesh;        ///< when ok: the finished mesh with the zone replaced
  /// Faces of `mesh` that are new (the patch and the band): a self-intersection test needs only these.
  std::vector<std::int64_t> newFaces;
  std::size_t removedFaces = 0, patchFaces = 0, bandFaces = 0, loops = 0;
  Mesh removed;  ///< the faces taken out of `finished` (with their vertices)
  Mesh patch;    ///< the faces put in (the finished patch and band)
  CleanReport clean;      ///< of the patch and band
  ProjectReport project;  ///< of the patch and band
};

/// f and ∇f through a field's evaluator, as finishSurfaces samples them.
FieldGradientSampler fieldGradientSampler(const FieldEvaluator& evaluator);

/// The cleaning and projection options finishSurfaces uses for a mesh extracted on cells of `cell` (the
/// field's bounds' largest side `side`).
CleanOptions finishCleanOptions(const MeshFinishOptions& options, double cell);
ProjectOptions finishProjectOptions(const MeshFinishOptions& options, double side, double cell);

/// The grid cell holding p (clamped to the grid).
std::array<int, 3> cellOf(const GridSpec& grid, const Eigen::Vector3d& p);

/// Boxes of grid cells (lo x, y, z, then hi x, y, z, inclusive) around the 26-connected clusters of
/// `cells` (sorted linear ids), `margin` cells wider on each side within the grid, overlapping boxes merged
/// into their bounding box: where the neck pass extracts its patch again.
std::vector<std::array<int, 6>> zoneBoxes(const GridSpec& grid, const std::vector<std::int64_t>& cells, int margin);

/// Grid cells within `radius` (Chebyshev) of `cells`, in the grid, as sorted linear ids
/// (x + nx·(y + ny·z)).
std::vector<std::int64_t> dilatedCells(const GridSpec& grid, const std::vector<std::array<int, 3>>& cells, int radius);

/// Replaces the faces of `finished` (closed, oriented, 2-manifold) whose centroid lies in a cell of
/// `outer` by the faces of `extracted` there that lie farther than ¾ of a cell from the faces that stay
/// (facing the same way), tidied into pieces that reach `inner` (inner ⊂ outer, one cell thinner; both
/// sorted linear ids of `grid`); strips of the hole with no patch face within 1.5 cells stay. The two are
/// joined by a band zipped between the boundary loops of the two. The patch and band are cleaned (`clean`;
/// their boundary, which is `finished`'s, is locked) and projected onto {f = iso} with their boundary held
/// (`project`). Not ok (nothing changed) when the boundaries are not simple loops that pair up one to one
/// within three cells.
SpliceResult spliceZone(const Mesh& finished, const Mesh& extracted, const GridSpec& grid,
                        const std::vector<std::int64_t>& inner, const std::vector<std::int64_t>& outer,
                        const FieldGradientSampler& sampler, double iso, double side, const CleanOptions& clean,
                        const ProjectOptions& project);

}  // namespace duplexfit::detail
