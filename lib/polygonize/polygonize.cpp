// GridSpec helpers and the polygonize() pipeline: validate, sample (sampling.cpp), extract
// (extract.cpp), with timings and progress/cancellation.
#include "duplexfit/polygonize.hpp"
#include "duplexfit/timer.hpp"

#include <chrono>
#include <cmath>
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
  if (o.threads < 0) {
    throw InvalidArgument("PolygonizeOptions::threads must be ≥ 0, got " +
                          std::to_string(o.threads));
  }
}

}  // namespace

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

PolygonizeResult polygonize(const FieldSampler& sampler, const GridSpec& grid,
                            const std::vector<double>& isoValues, const PolygonizeOptions& options,
                            const PolygonizeProgress& progress) {
  const auto start = std::chrono::steady_clock::now();
  const auto since = [](std::chrono::steady_clock::time_point t) {
    return secondsSince(t);
  };
  if (!sampler) throw InvalidArgument("polygonize: the sampler is empty");
  grid.validate();
  validateOptions(options);
  if (isoValues.empty()) throw InvalidArgument("polygonize: the list of iso values is empty");
  for (std::size_t q = 0; q < isoValues.size(); ++q) {
    if (!std::isfinite(isoValues[q])) {
      throw InvalidArgument("polygonize: iso value " + std::to_string(q) + " is not finite");
    }
  }
  const detail::ProgressReport report = [&progress](double fraction) {
    if (progress && !progress(fraction)) throw Cancelled("polygonize: cancelled");
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
  for (;;) {
    stats.storageBytes = store.bytes();
    const auto extractStart = std::chrono::steady_clock::now();
    detail::Extraction e = detail::extractMeshes(store, grid, isoValues, options.threads);
    stats.extractionSeconds += since(extractStart);
    if (e.openCells.empty()) {
      result.meshes = std::move(e.meshes);
      break;
    }
    const auto closeStart = std::chrono::steady_clock::now();
    stats.continuedCells +=
        detail::closeSurfaces(sampler, grid, isoValues, options, report, kSamplingShare, store,
                              stats, std::move(e.openCells));
    stats.samplingSeconds += since(closeStart);
  }
  report(1.0);
  stats.totalSeconds = since(start);
  return result;
}

}  // namespace duplexfit
