// The bilateral point filter of docs/method.md §9 (after Jones, Durand and Desbrun 2003): parameters from
// the spec's rules, neighbourhoods from the k-d tree (NeighborIndex) on the host packed as CSR lists, and the weighted sums on
// the device (kernels/preprocess.cl bilateral_filter) or its C++ twin.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/preprocess.hpp"
#include "preprocess/normals_internal.hpp"
#include "preprocess/preprocess_device.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

/// Queries per radius search: bounds the memory of the unsorted hit lists (about 60 hits × 12 bytes each).
constexpr Eigen::Index kQueryChunk = 131072;

/// α of σ_1 = αL (docs/method.md §4.4), as the fit uses by default.
constexpr double kAlpha = 0.75;

void checkLength(double v, const char* name) {
  if (!std::isfinite(v) || v < 0.0) {
    throw InvalidArgument(std::string("bilateralFilter: ") + name + " must be finite and >= 0 (0: default), got " +
                          std::to_string(v));
  }
}

/// N(q): points within r of each point (itself included).
std::vector<std::uint32_t> neighborCounts(const NeighborIndex& index, const Points& p, double r) {
  const Eigen::Index n = p.rows();
  std::vector<std::uint32_t> count(static_cast<std::size_t>(n));
  for (Eigen::Index b = 0; b < n; b += kQueryChunk) {
    const Eigen::Index m = std::min(kQueryChunk, n - b);
    const NeighborLists l = index.radiusSearch(p.middleRows(b, m), r);
    for (Eigen::Index i = 0; i < m; ++i) count[static_cast<std::size_t>(b + i)] = static_cast<std::uint32_t>(l.count(static_cast<std::size_t>(i)));
  }
  return count;
}

/// Neighbour lists within r as 32-bit CSR.
void neighborCsr(const NeighborIndex& index, const Points& p, double r, std::vector<std::uint32_t>& offsets,
                 std::vector<std::uint32_t>& nbr) {
  const Eigen::Index n = p.rows();
  offsets.assign(1, 0);
  offsets.reserve(static_cast<std::size_t>(n) + 1);
  nbr.clear();
  for (Eigen::Index b = 0; b < n; b += kQueryChunk) {
    const Eigen::Index m = std::min(kQueryChunk, n - b);
    const NeighborLists l = index.radiusSearch(p.middleRows(b, m), r);
    if (nbr.size() + l.indices.size() >= std::numeric_limits<std::uint32_t>::max()) {
      throw InvalidArgument("bilateralFilter: more than 2^32 neighbour pairs; use a smaller --radius");
    }
    nbr.insert(nbr.end(), l.indices.begin(), l.indices.end());
    for (Eigen::Index i = 0; i < m; ++i) {
      offsets.push_back(offsets.back() + static_cast<std::uint32_t>(l.count(static_cast<std::size_t>(i))));
    }
  }
}

}  // namespace

BilateralResult bilateralFilter(const Device& device, const PointSet& points, const BilateralOptions& options,
                                Interrupter* interrupter) {
  const auto start = Clock::now();
  checkLength(options.sigmaSpatial, "sigmaSpatial");
  checkLength(options.sigmaRange, "sigmaRange");
  checkLength(options.radius, "radius");
  checkLength(options.areaSigma, "areaSigma");
  if (options.iterations < 1 || options.iterations > 1000) {
    throw InvalidArgument("bilateralFilter: iterations must be between 1 and 1000, got " +
                          std::to_string(options.iterations));
  }
  if (options.reestimateNormals && options.normalK < 3) {
    throw InvalidArgument("bilateralFilter: normalK must be at least 3, got " + std::to_string(options.normalK));
  }
  device.requirePrecision(options.precision);
  const std::size_t n = points.size();
  if (n < 2) throw InvalidArgument("bilateralFilter: needs at least 2 points, got " + std::to_string(n));
  // Working copies (positions, shifts, normals, areas), the k-d tree and the neighbour lists' offsets.
  requireMemory(options.limits, "denoise", 300.0 * static_cast<double>(n), std::to_string(n) + " points",
                "filter a sparser cloud");
  const Points& in = points.positions();
  const Eigen::AlignedBox3d box = points.bounds();
  const double diag = box.diagonal().norm();
  if (!(diag > 0.0)) throw InvalidArgument("bilateralFilter: all " + std::to_string(n) + " points coincide");

  BilateralReport rep;
  rep.device = device.info().spec;
  rep.precision = options.precision;
  rep.points = n;
  rep.iterations = options.iterations;
  rep.symmetricRange = options.symmetricRange;

  // σ of the area weights: σ_M, the finest support of the fit's hierarchy (§4, §12.14).
  double sigma = options.areaSigma;
  if (sigma == 0.0) {
    const FitScales scales = fitScales(in, kAlpha);
    rep.levels = scales.levels;
    sigma = scales.sigmaFinest;
  }
  rep.areaSigma = sigma;

  // Centred working copy: the device sees small coordinates, displacements are added in double.
  const Eigen::RowVector3d centre = box.center().transpose();
  const Points centred = in.rowwise() - centre;
  Points shift = Points::Zero(in.rows(), 3);  // total displacement, so that an unmoved point stays bit-exact
  Points cur = centred;
  std::vector<double> nrm(3 * n);
  std::copy(points.normals().data(), points.normals().data() + 3 * n, nrm.begin());

  std::vector<std::uint32_t> offsets, nbr;
  std::vector<double> area(n), pos(3 * n);
  for (int pass = 0; pass < options.iterations; ++pass) {
    if (interrupter != nullptr && interrupter->wasInterrupted(100 * pass / options.iterations)) {
      throw Cancelled("bilateralFilter: cancelled before pass " + std::to_string(pass + 1));
    }
    auto t = Clock::now();
    const NeighborIndex index(cur);
    const std::vector<std::uint32_t> count = neighborCounts(index, cur, sigma);
    double rSum = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      area[i] = sigma * sigma / static_cast<double>(std::max<std::uint32_t>(count[i], 1));
      rSum += std::sqrt(area[i]);
    }
    if (pass == 0) {
      rep.rAve = rSum / static_cast<double>(n);
      rep.sigmaSpatial = options.sigmaSpatial > 0.0 ? options.sigmaSpatial : 4.0 * rep.rAve;
      rep.sigmaRange = options.sigmaRange > 0.0 ? options.sigmaRange : 4.0 * rep.rAve;
      rep.radius = options.radius > 0.0 ? options.radius : 2.0 * rep.sigmaSpatial;
    }
    neighborCsr(index, cur, rep.radius, offsets, nbr);
    rep.neighborSeconds += secondsSince(t);

    t = Clock::now();
    std::copy(cur.data(), cur.data() + 3 * n, pos.begin());
    const double a = 1.0 / (2.0 * rep.sigmaSpatial * rep.sigmaSpatial);
    const double b = 1.0 / ((options.symmetricRange ? 2.0 : 1.0) * rep.sigmaRange * rep.sigmaRange);
    const std::vector<double> disp = detail::bilateralPass(device, options.precision, pos, nrm, area, offsets, nbr, a, b);
    for (std::size_t i = 0; i < 3 * n; ++i) shift.data()[i] += disp[i];
    cur = centred + shift;
    rep.filterSeconds += secondsSince(t);
  }
  rep.meanNeighbors = static_cast<double>(nbr.size()) / static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i) rep.isolated += offsets[i + 1] - offsets[i] <= 1 ? 1 : 0;

  Points out = in + shift;
  double sum = 0.0;
  for (Eigen::Index i = 0; i < out.rows(); ++i) {
    const double d = (out.row(i) - in.row(i)).norm();
    sum += d;
    rep.maxDisplacement = std::max(rep.maxDisplacement, d);
    if (d > 1e-9 * diag) ++rep.moved;
  }
  rep.meanDisplacement = sum / static_cast<double>(n);

  Points normals = points.normals();
  if (options.reestimateNormals) {
    if (n < static_cast<std::size_t>(options.normalK) + 1) {
      throw InvalidArgument("bilateralFilter: re-estimating normals with normalK = " + std::to_string(options.normalK) +
                            " needs at least " + std::to_string(options.normalK + 1) + " points, got " +
                            std::to_string(n));
    }
    const detail::PcaNormals pca = detail::pcaNormals(device, options.precision, out, options.normalK, 0);
    for (Eigen::Index i = 0; i < out.rows(); ++i) {
      Eigen::RowVector3d v = pca.normals.row(i);
      if (v.dot(normals.row(i)) < 0.0) v = -v;
      // Keep the input normal where the new one is undefined, or where the input had none.
      if (v.squaredNorm() > 0.0 && normals.row(i).squaredNorm() > 0.0) normals.row(i) = v;
    }
    rep.normalsReestimated = true;
  }
  BilateralResult result{PointSet(std::move(out), std::move(normals)), rep};
  result.report.seconds = secondsSince(start);
  return result;
}

}  // namespace duplexfit
