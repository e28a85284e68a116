// Local refinement of the marching grid where it is too coarse for the field: cells whose node values
// show a layer one node thick (a plate or gap thinner than about two cells, which linear
// interpolation between nodes cannot follow) are split into a conforming finer tetrahedral mesh by
// newest-vertex bisection of their Kuhn tetrahedra (Maubach's tagged bisection, whose closure keeps
// the mesh conforming), and contoured there; the rest of the grid is contoured as before and the
// pieces weld along the unrefined faces around the refined region (docs/method.md §7).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/default_init.hpp"
#include "duplexfit/polygonize.hpp"
#include "node_store.hpp"

namespace duplexfit::detail {

/// A tetrahedron of the refined region, its corners on the lattice of the grid's nodes refined
/// `factor` = 2^levels times (node (i, j, k) is lattice point factor·(i, j, k)). Bisection halves
/// the edge x[0]–x[tag].
/// Trivially default-constructible (no member initialisers), so that the region's array of millions of them
/// is not zero-filled before it is copied into: every maker sets all fields (kuhnTets, bisect).
struct FineTet {
  std::array<std::array<std::int32_t, 3>, 4> x;
  std::uint8_t tag;
  std::uint8_t depth;
};

/// The cells in play and their leaf tetrahedra: the seed cells bisected 3·levels times each (their
/// tetrahedra have the size of cells `factor` times smaller) and the cells the conformity closure
/// touched. Every face between a cell in play and one outside is an unrefined face of the grid.
struct RefinedRegion {
  int levels = 0;
  std::int32_t factor = 1;
  std::vector<std::int64_t> cells;     ///< linear cell ids (i + nx·(j + ny·k)), ascending
  std::vector<std::size_t> offsets;    ///< tets of cells[c] are tets[offsets[c] .. offsets[c + 1])
  ScratchVector<FineTet> tets;
  std::int64_t seeds = 0;              ///< seed and ring cells
  /// Field values already evaluated at some of its lattice points (packed keys on this region's lattice),
  /// which extractRefined takes instead of evaluating them again (refinedDeviatingCells fills them).
  std::vector<std::uint64_t> knownKeys;
  std::vector<float> knownValues;
  bool skipped = false;                ///< more of them than refineCells' maxCells
  bool empty() const noexcept { return cells.empty(); }
  bool contains(std::int64_t cellId) const;
};

/// Appends the 6 Kuhn tetrahedra of cell c on the lattice refined `factor` times, corners ordered along
/// their monotone paths from the cell's lowest corner to its highest (tag 3).
void kuhnTets(const std::array<int, 3>& c, std::int32_t factor, std::vector<FineTet>& out);

/// Largest refinement level the grid's fine lattice can hold (0 when none): the doubled fine
/// coordinates of every axis must fit in 21 bits.
int maxRefineLevels(const Eigen::Vector3i& cells);

/// Refines the seed cells `levels` times and the other cells within `dilation` cells of them (clipped
/// to the grid) levels − 1 times, and closes the refinement so that the tetrahedral mesh is
/// conforming. Deterministic. With more than maxCells seed and ring cells, refines nothing (skipped).
/// deepSeeds (may be empty) are refined levels + 1 times and their neighbours within `dilation` levels times;
/// the region's factor is then 2^(levels + 1). With slabs = 2 (and enough seeds) the layers below and above
/// where the seeds' work halves are refined on two threads, each from the seeds near it, and joined: the
/// same region.
/// shallowSeeds (may be empty) are refined levels − 1 times, with no ring (the cells whose contour one level
/// less already follows the field: refinedDeviatingCells).
RefinedRegion refineCells(const Eigen::Vector3i& cells, const std::vector<std::array<int, 3>>& seeds,
                          int levels, int dilation, std::int64_t maxCells,
                          const std::vector<std::array<int, 3>>& deepSeeds = {}, int slabs = 1,
                          const std::vector<std::array<int, 3>>& shallowSeeds = {});

/// The contour of one iso value over the refined region: vertices keyed like the grid extraction's
/// (start node id · 8 + direction bits) when they lie on an unrefined grid edge, otherwise by
/// kFineKeyBit | the packed doubled fine coordinates of the edge's midpoint; triangles oriented with
/// normals toward decreasing f.
struct PatchMesh {
  static constexpr std::uint64_t kFineKeyBit = std::uint64_t{1} << 63;
  std::vector<std::uint64_t> keys;
  std::vector<double> xyz;
  std::vector<std::int32_t> tris;
};

/// Evaluates the field at points[0 .. n) in batches of at most batchSize (counted in stats:
/// refinedEvaluations, samplerCalls, samplerSeconds) and calls use(i, f(points[i])) for each; `what` names
/// the points in the error for a sampler that returns the wrong count.
void evaluateInBatches(const FieldSampler& sampler, const std::vector<Eigen::Vector3d>& points, std::int64_t batchSize,
                       PolygonizeStats& stats, const char* what, const std::function<void(std::size_t, double)>& use);

/// Of `candidates` (cells of `region`, a region refined one level less than wanted), those whose contour of
/// iso on the region's tetrahedra is farther than tol from the level set somewhere: the centre of a
/// tetrahedron's contour polygon (the mean of its edge crossings) has |f − iso| > tol (or f is not finite),
/// or the cell's lattice still has a layer one lattice point thick (a point whose two axis neighbours in the
/// cell lie on the other side of iso, whatever tol); a candidate outside the region counts as such. The values evaluated at the region's lattice points are
/// appended to knownKeys / knownValues, keyed on a lattice of factor toFactor (a multiple of the
/// region's). `within` (when not null) receives the other candidates, in their order.
std::vector<std::array<int, 3>> refinedDeviatingCells(const RefinedRegion& region,
                                                      const std::vector<std::array<int, 3>>& candidates,
                                                      const NodeStore& store, const GridSpec& grid, double iso,
                                                      const FieldSampler& sampler, double tol,
                                                      std::int64_t batchSize, PolygonizeStats& stats,
                                                      std::int32_t toFactor, std::vector<std::uint64_t>& knownKeys,
                                                      std::vector<float>& knownValues,
                                                      std::vector<std::array<int, 3>>* within = nullptr);

/// Contours the refined region for each iso value. Node values come from the store where sampled;
/// the other lattice points are evaluated with sampler (in batches of batchSize; counted in
/// stats.refinedEvaluations, samplerCalls and samplerSeconds). Appends to open the unmarked cells
/// outside the region that a contour enters through the region's boundary. Only the region's cells with
/// z index in [zBegin, zEnd) are contoured (a slab); the open neighbours are those of every region cell.
std::vector<PatchMesh> extractRefined(const RefinedRegion& region, const NodeStore& store,
                                      const GridSpec& grid, const std::vector<double>& isoValues,
                                      const FieldSampler& sampler, std::int64_t batchSize,
                                      PolygonizeStats& stats, std::vector<std::array<int, 3>>& open,
                                      int zBegin, int zEnd);

}  // namespace duplexfit::detail
