// GridSpec helpers and the polygonize() pipeline: validate, sample (sampling.cpp), extract
// (extract.cpp), with timings and progress/cancellation.
#include "duplexfit/polygonize.hpp"
#include "duplexfit/timer.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <utility>

#include "duplexfit/error.hpp"
#include "extract.hpp"
#include "node_store.hpp"
#include "sampling.hpp"

namespace duplexfit {

namespace {

const char* axisName(int a) { return a == 0 ? "x" : (a == 1 ? "y" : "z"); }

void checkBox(const Eigen::AlignedBox3d& box, const char* where) {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(box.min()(a)) || !std::isfinite(box.max()(a))) {
      throw InvalidArgument(std::string(where) + ": the box has a non-finite " + axisName(a) +
                            " bound");
    }
    if (!(box.max()(a) > box.min()(a))) {
      throw InvalidArgument(std::string(where) + ": the box is empty along " + axisName(a) +
                            " (max ≤ min)");
    }
  }
}

std::string tooManyNodes(double nodes) {
  std::ostringstream s;
  s << "GridSpec: " << nodes << " grid nodes exceed the limit of " << GridSpec::kMaxNodes;
  return s.str();
}

void validateOptions(const PolygonizeOptions& o) {
  if (!std::isfinite(o.lipschitz) || !(o.lipschitz > 0.0)) {
    throw InvalidArgument("PolygonizeOptions::lipschitz must be finite and > 0, got " +
                          std::to_string(o.lipschitz));
  }
  if (o.coarseStep < 2 || o.coarseStep > 64 || (o.coarseStep & (o.coarseStep - 1)) != 0) {
    throw InvalidArgument("PolygonizeOptions::coarseStep must be 2, 4, 8, 16, 32 or 64, got " +
                          std::to_string(o.coarseStep));
  }
  if (o.batchSize < 1) {
    throw InvalidArgument("PolygonizeOptions::batchSize must be ≥ 1, got " +
                          std::to_string(o.batchSize));
  }
  if (o.refineLevels < 0 || o.refineLevels > 3) {
    throw InvalidArgument("PolygonizeOptions::refineLevels must be 0 to 3, got " + std::to_string(o.refineLevels));
  }
  if (!o.refineDeeperCells.empty() && (o.refineLevels < 1 || o.refineLevels > 2)) {
    throw InvalidArgument("PolygonizeOptions::refineDeeperCells needs refineLevels 1 or 2, got " +
                          std::to_string(o.refineLevels));
  }
  if (o.refineDilation < 0 || o.refineDilation > 4) {
    throw InvalidArgument("PolygonizeOptions::refineDilation must be 0 to 4, got " + std::to_string(o.refineDilation));
  }
  if (!(o.refineTolerance >= 0.0) || !std::isfinite(o.refineTolerance)) {
    throw InvalidArgument("PolygonizeOptions::refineTolerance must be finite and ≥ 0, got " + std::to_string(o.refineTolerance));
  }
  if (o.maxRefinedCells < 0) {
    throw InvalidArgument("PolygonizeOptions::maxRefinedCells must be ≥ 0, got " + std::to_string(o.maxRefinedCells));
  }
  if (o.slabBegin < 0 || (o.slabEnd >= 0 && o.slabEnd <= o.slabBegin)) {
    throw InvalidArgument("PolygonizeOptions: the slab [" + std::to_string(o.slabBegin) + ", " +
                          std::to_string(o.slabEnd) + ") is empty or starts below 0");
  }
  if (o.threads < 0) {
    throw InvalidArgument("PolygonizeOptions::threads must be ≥ 0, got " +
                          std::to_string(o.threads));
  }
}

}  // namespace

int slabHalo(const PolygonizeOptions& options) {
  // The refinement of a cell depends on the thin cells within its ring (refineDilation) and on the
  // closure, which reaches a few cells further; whole blocks keep the adaptive sampling unchanged.
  const int t = std::max(1, options.coarseStep);
  const int reach = std::max(8, options.refineDilation + 2 * options.refineLevels + 3);
  return (reach + t - 1) / t * t;
}

GridSpec GridSpec::fromCellSize(const Eigen::AlignedBox3d& box, double cell) {
  if (!std::isfinite(cell) || !(cell > 0.0)) {
    throw InvalidArgument("GridSpec::fromCellSize: the cell size must be finite and > 0, got " +
                          std::to_string(cell));
  }
  checkBox(box, "GridSpec::fromCellSize");
  GridSpec grid;
  double nodes = 1.0;
  double counts[3];
  for (int a = 0; a < 3; ++a) {
    // A relative slack keeps an extent that is an exact multiple of cell from gaining a cell.
    counts[a] = std::max(1.0, std::ceil(box.sizes()(a) / cell * (1.0 - 1e-9)));
    nodes *= counts[a] + 1.0;
  }
  if (nodes > static_cast<double>(kMaxNodes)) throw InvalidArgument(tooManyNodes(nodes));
  const Eigen::Vector3d centre = box.center();
  for (int a = 0; a < 3; ++a) {
    grid.cells(a) = static_cast<int>(counts[a]);
    const double half = 0.5 * counts[a] * cell;
    grid.box.min()(a) = centre(a) - half;
    grid.box.max()(a) = centre(a) + half;
  }
  return grid;
}

void GridSpec::validate() const {
  for (int a = 0; a < 3; ++a) {
    if (cells(a) < 1) {
      throw InvalidArgument(std::string("GridSpec::cells(") + std::to_string(a) +
                            ") must be ≥ 1, got " + std::to_string(cells(a)));
    }
  }
  checkBox(box, "GridSpec");
  const double nodes = (cells(0) + 1.0) * (cells(1) + 1.0) * (cells(2) + 1.0);
  if (nodes > static_cast<double>(kMaxNodes)) throw InvalidArgument(tooManyNodes(nodes));
}

Eigen::Vector3d GridSpec::cellSize() const {
  return (box.max() - box.min()).cwiseQuotient(cells.cast<double>());
}

std::int64_t GridSpec::nodeCount() const {
  return (cells(0) + std::int64_t{1}) * (cells(1) + std::int64_t{1}) * (cells(2) + std::int64_t{1});
}

Eigen::Vector3d GridSpec::node(int i, int j, int k) const {
  const int idx[3] = {i, j, k};
  Eigen::Vector3d p;
  for (int a = 0; a < 3; ++a) {
    p(a) = detail::nodeCoordinate(box.min()(a), box.max()(a), cells(a), idx[a]);
  }
  return p;
}

PolygonizeEstimate estimatePolygonize(const GridSpec& grid, std::size_t isoCount, const PolygonizeOptions& options) {
  PolygonizeEstimate e;
  const double tile = options.coarseStep;
  const double tile3 = tile * tile * tile;
  double cells[3], tiles[3], coarse[3];
  e.nodes = 1.0;
  double tileCount = 1.0, coarseNodes = 1.0;
  for (int a = 0; a < 3; ++a) {
    cells[a] = std::max(1, grid.cells(a));
    e.nodes *= cells[a] + 1.0;
    tiles[a] = std::floor(cells[a] / tile) + 1.0;  // as NodeStore
    coarse[a] = std::ceil(cells[a] / tile) + 1.0;
    tileCount *= tiles[a];
    coarseNodes *= coarse[a];
  }
  const double levels = static_cast<double>(std::max<std::size_t>(1, isoCount));
  double storedTiles = tileCount;
  if (options.adaptive) {
    const double boxTiles = 2.0 * (tiles[0] * tiles[1] + tiles[1] * tiles[2] + tiles[0] * tiles[2]);
    storedTiles = std::min(tileCount, 2.0 * levels * boxTiles);
  }
  e.storedNodes = storedTiles * tile3;
  // Two pointers per tile (values, marks), the coarse lattice, the tiles' floats and their cell-mark bits.
  e.storeBytes = 16.0 * tileCount + (options.adaptive ? 4.0 * coarseNodes : 0.0) + storedTiles * tile3 * (4.0 + 1.0 / 8.0);
  const double boxCells = 2.0 * (cells[0] * cells[1] + cells[1] * cells[2] + cells[0] * cells[2]);
  e.triangles = 4.0 * levels * boxCells;
  // A triangle: 12 bytes of indices and half a vertex of 24 bytes in the mesh, as much again in the
  // per-thread pieces, and the edge-to-vertex welding map.
  e.meshBytes = 64.0 * e.triangles;
  return e;
}

void checkPolygonizeMemory(const GridSpec& grid, std::size_t isoCount, const PolygonizeOptions& options) {
  const PolygonizeEstimate e = estimatePolygonize(grid, isoCount, options);
  std::ostringstream what;
  what.precision(3);
  what << "the " << grid.cells(0) << "x" << grid.cells(1) << "x" << grid.cells(2) << " grid (" << e.nodes
       << " nodes, about " << e.triangles << " triangles) with " << isoCount << " level set"
       << (isoCount == 1 ? "" : "s");
  requireMemory(options.limits, "polygonize", e.bytes(), what.str(), "use a larger --cell or a smaller --resolution");
}

Mesh weldByKeys(const std::vector<const Mesh*>& pieces, const std::vector<const std::vector<std::uint64_t>*>& keys) {
  if (pieces.size() != keys.size()) {
    throw InvalidArgument("weldByKeys: " + std::to_string(pieces.size()) + " meshes with " +
                          std::to_string(keys.size()) + " key lists");
  }
  // (key, piece, vertex), sorted by key then by position in the input: the first of each key wins.
  struct Entry {
    std::uint64_t key;
    std::uint32_t piece;
    std::int32_t vertex;
  };
  std::vector<Entry> entries;
  std::int64_t faces = 0;
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    const Mesh& m = *pieces[p];
    if (static_cast<Eigen::Index>(keys[p]->size()) != m.vertices.rows()) {
      throw InvalidArgument("weldByKeys: piece " + std::to_string(p) + " has " + std::to_string(m.vertices.rows()) +
                            " vertices and " + std::to_string(keys[p]->size()) + " keys");
    }
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
      entries.push_back({(*keys[p])[static_cast<std::size_t>(v)], static_cast<std::uint32_t>(p), static_cast<std::int32_t>(v)});
    }
    faces += m.faces.rows();
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.key != b.key ? a.key < b.key : (a.piece != b.piece ? a.piece < b.piece : a.vertex < b.vertex);
  });
  // Each key's first (piece, vertex) owns it; global ids in the order of first appearance.
  std::vector<std::pair<std::uint32_t, std::int32_t>> owner(entries.size());
  for (std::size_t i = 0; i < entries.size();) {
    std::size_t j = i;
    while (j < entries.size() && entries[j].key == entries[i].key) ++j;
    for (std::size_t k = i; k < j; ++k) owner[k] = {entries[i].piece, entries[i].vertex};
    i = j;
  }
  std::vector<std::vector<std::int32_t>> global(pieces.size());
  for (std::size_t p = 0; p < pieces.size(); ++p) global[p].assign(static_cast<std::size_t>(pieces[p]->vertices.rows()), -1);
  // Unique vertices numbered in input order: walk the pieces, giving each owner vertex the next id.
  std::vector<std::vector<std::pair<std::uint32_t, std::int32_t>>> ownerOf(pieces.size());
  for (std::size_t p = 0; p < pieces.size(); ++p) ownerOf[p].resize(static_cast<std::size_t>(pieces[p]->vertices.rows()));
  for (std::size_t k = 0; k < entries.size(); ++k) ownerOf[entries[k].piece][static_cast<std::size_t>(entries[k].vertex)] = owner[k];
  std::int64_t next = 0;
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    for (std::size_t v = 0; v < ownerOf[p].size(); ++v) {
      const auto [op, ov] = ownerOf[p][v];
      if (op == p && static_cast<std::size_t>(ov) == v) global[p][v] = static_cast<std::int32_t>(next++);
    }
  }
  if (next > std::numeric_limits<std::int32_t>::max()) {
    throw InvalidArgument("weldByKeys: more than 2^31 - 1 vertices");
  }
  Mesh out;
  out.vertices.resize(next, 3);
  out.faces.resize(faces, 3);
  std::int64_t f = 0;
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    const Mesh& m = *pieces[p];
    for (std::size_t v = 0; v < ownerOf[p].size(); ++v) {
      const std::int32_t g = global[p][v];
      if (g >= 0) out.vertices.row(g) = m.vertices.row(static_cast<Eigen::Index>(v));
    }
    for (Eigen::Index t = 0; t < m.faces.rows(); ++t, ++f) {
      for (int c = 0; c < 3; ++c) {
        const Index x = m.faces(t, c);
        if (x < 0 || x >= m.vertices.rows()) {
          throw InvalidArgument("weldByKeys: face " + std::to_string(t) + " of piece " + std::to_string(p) +
                                " has vertex index " + std::to_string(x) + " outside [0, " +
                                std::to_string(m.vertices.rows()) + ")");
        }
        const auto [op, ov] = ownerOf[p][static_cast<std::size_t>(x)];
        out.faces(f, c) = global[op][static_cast<std::size_t>(ov)];
      }
    }
  }
  return out;
}

PolygonizeResult polygonize(const FieldSampler& sampler, const GridSpec& grid,
                            const std::vector<double>& isoValues, const PolygonizeOptions& options,
                            Interrupter* interrupter) {
  const auto start = std::chrono::steady_clock::now();
  const auto since = [](std::chrono::steady_clock::time_point t) {
    return secondsSince(t);
  };
  if (!sampler) throw InvalidArgument("polygonize: the sampler is empty");
  grid.validate();
  validateOptions(options);
  if (options.slabEnd > grid.cells(2) || options.slabBegin >= grid.cells(2)) {
    throw InvalidArgument("polygonize: the slab [" + std::to_string(options.slabBegin) + ", " +
                          std::to_string(options.slabEnd) + ") is outside the grid's " +
                          std::to_string(grid.cells(2)) + " cells along z");
  }
  if (isoValues.empty()) throw InvalidArgument("polygonize: the list of iso values is empty");
  for (std::size_t q = 0; q < isoValues.size(); ++q) {
    if (!std::isfinite(isoValues[q])) {
      throw InvalidArgument("polygonize: iso value " + std::to_string(q) + " is not finite");
    }
  }
  checkPolygonizeMemory(grid, isoValues.size(), options);
  const detail::ProgressReport report = [interrupter](double fraction) {
    if (interrupter != nullptr && interrupter->wasInterrupted(static_cast<int>(std::lround(100.0 * fraction)))) {
      throw Cancelled("polygonize: cancelled");
    }
  };

  PolygonizeResult result;
  PolygonizeStats& stats = result.stats;
  stats.totalNodes = grid.nodeCount();
  detail::NodeStore store(grid.cells, options.coarseStep);
  constexpr double kSamplingShare = 0.9;  // of the progress range
  detail::sampleNodes(sampler, grid, isoValues, options, report, kSamplingShare, store, stats);
  stats.samplingSeconds = since(start);

  // Extraction reports surfaces that leave the contoured cells (possible only where |∇f| exceeds
  // the Lipschitz bound); those are followed cell by cell and the extraction is repeated, so that
  // every mesh stays closed.
  detail::RefineCache refineCache;  // what a repeated extraction reuses
  for (;;) {
    stats.storageBytes = store.bytes();
    const auto extractStart = std::chrono::steady_clock::now();
    detail::Extraction e = detail::extractMeshes(store, grid, isoValues, options, sampler, stats, &refineCache);
    stats.extractionSeconds += since(extractStart);
    ++stats.extractionRounds;
    if (e.openCells.empty()) {
      result.meshes = std::move(e.meshes);
      result.vertexKeys = std::move(e.vertexKeys);
      break;
    }
    const auto closeStart = std::chrono::steady_clock::now();
    refineCache.changedZ.assign(static_cast<std::size_t>(grid.cells(2)), 0);
    const std::int64_t added =
        detail::closeSurfaces(sampler, grid, isoValues, options, report, kSamplingShare, store,
                              stats, std::move(e.openCells), &refineCache.changedZ);
    stats.continuedCells += added;
    // Every open cell is unmarked when reported and gets marked, so each round adds cells; should one
    // add none, the next round contours every chunk again instead of taking any as it was.
    if (added == 0) refineCache.chunks.reset();
    stats.samplingSeconds += since(closeStart);
  }
  report(1.0);
  stats.totalSeconds = since(start);
  return result;
}

}  // namespace duplexfit
