// Marching tetrahedra over the sampled cells of a NodeStore: one welded, oriented mesh per iso
// value, built in parallel over z-ranges of cells and merged deterministically.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

#include "duplexfit/mesh.hpp"
#include "duplexfit/polygonize.hpp"
#include "node_store.hpp"
#include "refine.hpp"

namespace duplexfit::detail {

/// Meshes, one per iso value, or (with no meshes) the unmarked cells that contoured surfaces enter.
struct Extraction {
  std::vector<Mesh> meshes;
  std::vector<std::vector<std::uint64_t>> vertexKeys;  ///< with options.keepVertexKeys or a slab
  std::vector<std::array<int, 3>> openCells;
};

/// Contours every marked cell for each iso value (see polygonize()). When a surface leaves the
/// marked cells through a face that is not on the grid boundary, returns those neighbour cells
/// (possibly repeated) instead of meshes; otherwise returns the meshes and releases the store's
/// memory. Cells with a node layer one node thick (and options.refineCells) are contoured on a locally
/// refined grid (refine.hpp), with their extra points evaluated through sampler; stats gets the
/// refinement's counts. With a slab (PolygonizeOptions::slabBegin/End), only its cells are contoured;
/// the sampled cells around it are scanned for thin cells and open neighbours as the whole grid would be. options.threads: OpenMP threads, 0 = default; the result does not depend on it.
/// What one extraction round leaves for the next (polygonize repeats the extraction after sampling the
/// cells a surface left through): per iso value, the tolerance test of each thin cell (its 8 node values
/// never change) and the last refined region with the seeds it was built from.
struct RefineCache {
  std::vector<std::unordered_map<std::int64_t, bool>> deviating;
  std::vector<std::vector<std::array<int, 3>>> seeds;
  std::vector<RefinedRegion> regions;
  std::vector<char> built;  ///< regions[q] was built in an earlier round
  /// The contoured chunks of a round that ended with open cells (extract.cpp), and per cell layer z
  /// whether the caller marked cells there since (`changedZ`, sized by the caller): a chunk whose layers
  /// and their neighbours did not change, under the same refined regions, is taken as it was.
  std::shared_ptr<struct ChunkCache> chunks;
  std::vector<char> changedZ;
};

Extraction extractMeshes(NodeStore& store, const GridSpec& grid, const std::vector<double>& isoValues,
                         const PolygonizeOptions& options, const FieldSampler& sampler,
                         PolygonizeStats& stats, RefineCache* cache = nullptr);

}  // namespace duplexfit::detail
