// Level-set extraction of a fitted field: grid choice (docs/method.md §7, §12 item 15) and a device-backed
// sampler for the polygonizer.
#include "duplexfit/surfaces.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "duplexfit/error.hpp"

namespace duplexfit {

GridSpec surfaceGrid(const ImplicitField& field, const std::vector<double>& isoValues, const SurfaceOptions& options) {
  if (field.levels().empty()) throw InvalidArgument("surface extraction: the field has no levels");
  return surfaceGrid(field.bounds(), field.levels().back().sigma / field.normalization().scale, isoValues, options);
}

GridSpec surfaceGrid(const Eigen::AlignedBox3d& b, double sigmaM, const std::vector<double>& isoValues,
                     const SurfaceOptions& options) {
  if (!(options.cell >= 0.0) || options.resolution < 0 || options.maxResolution < 8 || options.minResolution < 1 ||
      options.minResolution > options.maxResolution) {
    throw InvalidArgument("surface extraction: cell must be >= 0, resolution >= 0, maxResolution >= 8 and "
                          "1 <= minResolution <= maxResolution");
  }
  const double side = b.sizes().maxCoeff();
  double cell = options.cell;
  if (options.resolution > 0) {
    cell = side / options.resolution;
  } else if (cell == 0.0) {
    // σ_M/2 only: the paper's min|δ|/4 term made the triangle count grow as 1/δ² (maxplanck_12k, both
    // meshes: 1.5M triangles at δ = 0.02, 10.6M at 0.005), while at δ = 0.02 the offset mesh's largest
    // deviation from its level set was 1.0% of the box with either rule (docs/method.md §7).
    cell = sigmaM / 2.0;
    // Sparse clouds have a coarse finest level (σ_M/2 of a 180-point sphere is 0.16 of its side): keep at
    // least minResolution cells along the longest side so the meshes stay close to the field.
    cell = std::min(cell, side / options.minResolution);
    cell = std::max(cell, side / options.maxResolution);
  }
  // Outward offsets (negative iso) lie outside the input bounds by |δ|; the fit can also bulge a little
  // past sparse or flat regions, hence 5% of the largest side on top.
  double pad = 0.0;
  for (double iso : isoValues) pad = std::max(pad, -iso);
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(pad + 0.05 * side + 3.0 * cell);
  return GridSpec::fromCellSize(Eigen::AlignedBox3d(b.min() - margin, b.max() + margin), cell);
}

PolygonizeOptions surfacePolygonizeOptions(const ImplicitField& field, const SurfaceOptions& options) {
  PolygonizeOptions o = options.polygonize;
  if (o.refineTolerance == 0.0) o.refineTolerance = options.refineTolerance * field.bounds().sizes().maxCoeff();
  return o;
}

FieldSampler valueSampler(const FieldEvaluator& evaluator) {
  return [&evaluator](const Points& queries, Eigen::VectorXd& values) { values = evaluator.evaluate(queries).values; };
}

std::array<double, 6> boundaryContacts(const std::vector<Mesh>& meshes, const GridSpec& grid) {
  const Eigen::Vector3d lo = grid.box.min(), hi = grid.box.max();
  const double eps = 1e-9 * (hi - lo).maxCoeff();
  std::array<double, 6> touch{};
  for (const Mesh& m : meshes) {
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
      for (int a = 0; a < 3; ++a) {
        if (m.vertices(v, a) <= lo[a] + eps) touch[static_cast<std::size_t>(a)] = 1.0;
        if (m.vertices(v, a) >= hi[a] - eps) touch[static_cast<std::size_t>(3 + a)] = 1.0;
      }
    }
  }
  return touch;
}

GridSpec grownGrid(const GridSpec& grid, const std::array<double, 6>& contacts) {
  const Eigen::Vector3d lo = grid.box.min(), hi = grid.box.max();
  const double step = 0.1 * (hi - lo).maxCoeff();
  Eigen::Vector3d growLo, growHi;
  for (int a = 0; a < 3; ++a) {
    growLo(a) = contacts[static_cast<std::size_t>(a)] > 0.0 ? step : 0.0;
    growHi(a) = contacts[static_cast<std::size_t>(3 + a)] > 0.0 ? step : 0.0;
  }
  return GridSpec::fromCellSize(Eigen::AlignedBox3d(lo - growLo, hi + growHi), grid.cellSize().maxCoeff());
}

SurfaceResult extractSurfaces(const Device& device, const ImplicitField& field, const std::vector<double>& isoValues,
                              const SurfaceOptions& options, Interrupter* interrupter) {
  if (isoValues.empty()) throw InvalidArgument("surface extraction: no iso values given");
  const FieldEvaluator evaluator(device, field, options.precision);
  return extractSurfaces(evaluator, field, isoValues, options, interrupter);
}

SurfaceResult extractSurfaces(const FieldEvaluator& evaluator, const ImplicitField& field,
                              const std::vector<double>& isoValues, const SurfaceOptions& options,
                              Interrupter* interrupter) {
  if (isoValues.empty()) throw InvalidArgument("surface extraction: no iso values given");
  if (evaluator.levelCount() != static_cast<int>(field.levels().size())) {
    throw InvalidArgument("surface extraction: the evaluator holds " + std::to_string(evaluator.levelCount()) +
                          " levels, the field " + std::to_string(field.levels().size()));
  }
  SurfaceResult out;
  out.grid = surfaceGrid(field, isoValues, options);
  const FieldSampler sampler = valueSampler(evaluator);
  // A level set that reaches the grid's boundary would be cut open there: grow the box on the sides
  // it touches (same cell size) and extract again, a few times at most.
  const PolygonizeOptions polygonizeOptions = surfacePolygonizeOptions(field, options);
  for (int attempt = 0;; ++attempt) {
    PolygonizeResult r = polygonize(sampler, out.grid, isoValues, polygonizeOptions, interrupter);
    const std::array<double, 6> touch = boundaryContacts(r.meshes, out.grid);
    const bool touches = std::any_of(touch.begin(), touch.end(), [](double t) { return t > 0.0; });
    out.boxGrowths = attempt;
    if (!touches || attempt >= 3) {
      out.meshes = std::move(r.meshes);
      out.stats = r.stats;
      out.touchesBoundary = touches;
      return out;
    }
    out.grid = grownGrid(out.grid, touch);
  }
}

}  // namespace duplexfit
