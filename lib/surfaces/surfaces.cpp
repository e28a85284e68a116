// Level-set extraction of a fitted field: grid choice (algorithm.md §7, §12 item 15) and a device-backed
// sampler for the polygonizer.
#include "duplexfit/surfaces.hpp"

#include <algorithm>
#include <cmath>

#include "duplexfit/error.hpp"

namespace duplexfit {

GridSpec surfaceGrid(const ImplicitField& field, const std::vector<double>& isoValues, const SurfaceOptions& options) {
  if (field.levels().empty()) throw InvalidArgument("surface extraction: the field has no levels");
  if (!(options.cell >= 0.0) || options.resolution < 0 || options.maxResolution < 8) {
    throw InvalidArgument("surface extraction: cell must be >= 0, resolution >= 0 and maxResolution >= 8");
  }
  const Eigen::AlignedBox3d& b = field.bounds();
  const double side = b.sizes().maxCoeff();
  double cell = options.cell;
  if (options.resolution > 0) {
    cell = side / options.resolution;
  } else if (cell == 0.0) {
    const double sigmaM = field.levels().back().sigma / field.normalization().scale;
    cell = sigmaM / 2.0;
    for (double iso : isoValues) {
      if (iso != 0.0) cell = std::min(cell, std::abs(iso) / 4.0);
    }
    cell = std::max(cell, side / options.maxResolution);
  }
  // Outward offsets (negative iso) lie outside the input bounds by |δ|.
  double pad = 0.0;
  for (double iso : isoValues) pad = std::max(pad, -iso);
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(pad + 3.0 * cell);
  return GridSpec::fromCellSize(Eigen::AlignedBox3d(b.min() - margin, b.max() + margin), cell);
}

SurfaceResult extractSurfaces(const Device& device, const ImplicitField& field, const std::vector<double>& isoValues,
                              const SurfaceOptions& options, const PolygonizeProgress& progress) {
  if (isoValues.empty()) throw InvalidArgument("surface extraction: no iso values given");
  SurfaceResult out;
  out.grid = surfaceGrid(field, isoValues, options);
  const FieldEvaluator evaluator(device, field, options.precision);
  const FieldSampler sampler = [&evaluator](const Points& queries, Eigen::VectorXd& values) {
    values = evaluator.evaluate(queries).values;
  };
  PolygonizeResult r = polygonize(sampler, out.grid, isoValues, options.polygonize, progress);
  out.meshes = std::move(r.meshes);
  out.stats = r.stats;
  return out;
}

}  // namespace duplexfit
