// Sampling of grid node values for polygonisation: every node (full mode) or a coarse lattice plus
// recursive block refinement near the requested level sets under a Lipschitz bound (adaptive mode).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "duplexfit/polygonize.hpp"
#include "node_store.hpp"

namespace duplexfit::detail {

/// Node coordinates along each axis: c[a][i] = box.min(a) + i·h(a), and exactly box.max(a) for the
/// last node (GridSpec::node uses the same rule).
std::array<std::vector<double>, 3> nodeCoordinates(const GridSpec& grid);

/// Coordinate of node i of n cells on [lo, hi].
inline double nodeCoordinate(double lo, double hi, int n, int i) {
  return i == n ? hi : lo + static_cast<double>(i) * ((hi - lo) / static_cast<double>(n));
}

/// A range [begin, end) of cell z indices.
struct ZRange {
  int begin = 0;
  int end = 0;
  bool contains(int k) const noexcept { return k >= begin && k < end; }
};

/// The cells a slab contours (PolygonizeOptions::slabBegin/End; the whole grid without a slab), for a
/// grid of nz cells along z.
ZRange slabCells(const PolygonizeOptions& options, int nz);

/// The cells sampled for it: the slab and slabHalo cells on each side, grown to whole blocks of
/// coarseStep cells (so that every block is refined as in the whole grid's sampling) and clipped to the grid.
ZRange sampledCells(const PolygonizeOptions& options, int nz);

/// Called with the overall progress fraction; throws Cancelled when the user asks to stop.
using ProgressReport = std::function<void(double fraction)>;

/// Fills store (built with tile = options.coarseStep) with sampled node values (of the cells in
/// sampledCells(options, nz) only) and updates
/// stats.evaluatedNodes, samplerCalls, coarseBlocks, refinedBlocks and samplerSeconds. Progress is
/// reported as fractions of [0, progressEnd].
void sampleNodes(const FieldSampler& sampler, const GridSpec& grid,
                 const std::vector<double>& isoValues, const PolygonizeOptions& options,
                 const ProgressReport& report, double progressEnd, NodeStore& store,
                 PolygonizeStats& stats);

/// The 6 faces of a cell: {axis, side (−1 or +1), corner bitmask of the face's 4 nodes}.
const std::array<std::array<int, 3>, 6>& cellFaces();

/// Appends to out the unmarked in-grid neighbours of a cell (corner values v, all sampled) across
/// faces where some iso value changes sign: cells the surface enters from this one.
void appendOpenNeighbours(const NodeStore& store, const std::array<int, 3>& cell, const float* v,
                          const std::vector<double>& isoValues,
                          std::vector<std::array<int, 3>>& out);

/// Continuation where the adaptive pass left a surface open (|∇f| exceeded the Lipschitz bound):
/// marks and samples the given cells, then every unmarked cell the surface enters from a marked
/// one, until every surface is closed (cells outside sampledCells(options, nz) are left: another slab's).
/// Returns the number of cells added; `changedZ` (when not null, one entry per cell layer) gets 1 at the
/// layer of every cell it marks.
std::int64_t closeSurfaces(const FieldSampler& sampler, const GridSpec& grid,
                           const std::vector<double>& isoValues, const PolygonizeOptions& options,
                           const ProgressReport& report, double progress, NodeStore& store,
                           PolygonizeStats& stats, std::vector<std::array<int, 3>> cells,
                           std::vector<char>* changedZ = nullptr);

}  // namespace duplexfit::detail
