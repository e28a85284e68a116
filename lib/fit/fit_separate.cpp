// The separate-fit baseline: one field for the surface and one for each offset surface, each fitted from
// its own points (the comparison of the paper's Table 1).
#include <chrono>
#include <cmath>
#include <sstream>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/fit.hpp"
#include "fit/constraints.hpp"

namespace duplexfit {

PointSet offsetPointCloud(const PointSet& points, double delta, bool normalsInward, double eta, bool sideTest) {
  if (delta == 0.0 || !std::isfinite(delta)) throw InvalidArgument("offsetPointCloud: the offset must be finite and non-zero");
  // Unit inward normals ν (zero normals stay zero and produce no offset point).
  Points nu(points.normals().rows(), 3);
  for (Eigen::Index i = 0; i < nu.rows(); ++i) {
    const Eigen::RowVector3d n = points.normals().row(i);
    const double len = n.norm();
    nu.row(i) = len > 0.0 ? Eigen::RowVector3d((normalsInward ? 1.0 : -1.0) * n / len) : Eigen::RowVector3d::Zero();
  }
  std::vector<Eigen::Index> sources;
  Points q = detail::validOffsetPoints(points.positions(), nu, delta, eta, sideTest, sources);
  if (q.rows() == 0) {
    std::ostringstream msg;
    msg << "offset " << delta << ": no offset point passed the validity test (the offset is larger than the shape)";
    throw InvalidArgument(msg.str());
  }
  Points normals(q.rows(), 3);
  for (std::size_t k = 0; k < sources.size(); ++k) {
    normals.row(static_cast<Eigen::Index>(k)) = points.normals().row(sources[k]);
  }
  return PointSet(std::move(q), std::move(normals));
}

SeparateFitResult fitSeparate(const Device& device, const PointSet& points, const FitOptions& options,
                              Interrupter* interrupter) {
  const auto start = std::chrono::steady_clock::now();
  if (points.size() == 0) throw InvalidArgument("fit: the cloud is empty");
  const double side = points.bounds().sizes().maxCoeff();
  SeparateFitResult out;
  FitOptions single = options;
  single.offsets.clear();
  single.offsetsRelative = false;
  auto announce = [&](const std::string& what) {
    if (interrupter == nullptr) return;
    interrupter->fitEvent({FitStage::Start, 0, 0, 0, 0.0, what});
    if (interrupter->wasInterrupted()) throw Cancelled("fit cancelled before the " + what + " fit");
  };
  // Checked before any work.
  const std::vector<double> deltas = detail::worldOffsets(options.offsets, options.offsetsRelative, side);
  announce("surface");
  FitResult zero = fit(device, points, single, interrupter);
  out.zero = std::move(zero.field);
  out.zeroReport = std::move(zero.report);
  for (const double world : deltas) {
    const PointSet cloud =
        offsetPointCloud(points, world, options.normalsInward, options.validityTolerance, options.sideTest);
    announce("offset " + std::to_string(out.offsets.size() + 1));
    FitResult r = fit(device, cloud, single, interrupter);
    out.offsets.push_back(std::move(r.field));
    out.offsetReports.push_back(std::move(r.report));
    out.offsetDeltas.push_back(world);
    out.offsetPoints.push_back(cloud.size());
  }
  out.secondsTotal = secondsSince(start);
  return out;
}

}  // namespace duplexfit
