// Offset and off-surface points with the validity test of algorithm.md §3.1–§3.2, and the merge of
// near-duplicate centres (§3.5), using the FLANN-backed NeighborIndex.
#include "fit/constraints.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"

namespace duplexfit::detail {

namespace {

// Candidates q = p_i + step·ν_i for points with a non-zero normal, kept when the nearest point p_j of P
// other than p_i is at least |step|(1 − η) away (§3.1) and, with `sideTest`, q lies on the step's side of
// p_j's tangent plane: sign(step)·(q − p_j)·ν_j > 0. The side test (ours, optional) rejects companions
// that land behind the surface (e.g. from normals flipped against their neighbours', which plant a
// spurious closed sheet outside the solid); it can also reject valid companions of coarse levels, where
// the surface's curvature between cell centroids exceeds |step|. Returns the kept candidates and their
// source indices.
Points validCompanions(const Points& points, const Points& normals, const NeighborIndex& index, double step,
                       double eta, bool sideTest, std::size_t& candidates,
                       std::vector<Eigen::Index>* keptSources = nullptr) {
  std::vector<Eigen::Index> source;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    if (normals.row(i).squaredNorm() > 0.0) source.push_back(i);
  }
  candidates = source.size();
  Points q(static_cast<Eigen::Index>(source.size()), 3);
  for (std::size_t k = 0; k < source.size(); ++k) {
    const Eigen::Index i = source[k];
    q.row(static_cast<Eigen::Index>(k)) = points.row(i) + step * normals.row(i);
  }
  const NeighborLists nn = index.knnSearch(q, 2);
  const double limit = std::abs(step) * (1.0 - eta);
  std::vector<char> keep(source.size(), 0);
  std::size_t kept = 0;
  const double sign = step > 0.0 ? 1.0 : -1.0;
  for (std::size_t k = 0; k < source.size(); ++k) {
    double nearestOther = std::numeric_limits<double>::infinity();
    Eigen::Index other = -1;
    for (auto e = nn.offsets[k]; e < nn.offsets[k + 1]; ++e) {
      if (nn.indices[static_cast<std::size_t>(e)] != source[k]) {
        nearestOther = nn.distances[static_cast<std::size_t>(e)];
        other = nn.indices[static_cast<std::size_t>(e)];
        break;
      }
    }
    bool ok = nearestOther >= limit;
    if (sideTest && ok && other >= 0 && normals.row(other).squaredNorm() > 0.0) {
      ok = sign * (q.row(static_cast<Eigen::Index>(k)) - points.row(other)).dot(normals.row(other)) > 0.0;
    }
    keep[k] = ok ? 1 : 0;
    kept += static_cast<std::size_t>(keep[k]);
  }
  Points out(static_cast<Eigen::Index>(kept), 3);
  Eigen::Index r = 0;
  if (keptSources != nullptr) keptSources->clear();
  for (std::size_t k = 0; k < source.size(); ++k) {
    if (keep[k] == 0) continue;
    out.row(r++) = q.row(static_cast<Eigen::Index>(k));
    if (keptSources != nullptr) keptSources->push_back(source[k]);
  }
  return out;
}

}  // namespace

std::vector<double> worldOffsets(const std::vector<double>& offsets, bool relative, double side) {
  std::vector<double> out;
  for (const double d : offsets) {
    const double world = relative ? d * side : d;
    if (world == 0.0) throw InvalidArgument("fit options: an offset of 0 is the surface itself; give a non-zero offset");
    if (std::abs(world) >= side) {
      std::ostringstream msg;
      msg << "fit options: offset " << world << " is not smaller than the bounding box's largest side " << side;
      throw InvalidArgument(msg.str());
    }
    out.push_back(world);
  }
  return out;
}

Points validOffsetPoints(const Points& points, const Points& normals, double step, double eta, bool sideTest,
                         std::vector<Eigen::Index>& sources) {
  const NeighborIndex index(points);
  std::size_t candidates = 0;
  return validCompanions(points, normals, index, step, eta, sideTest, candidates, &sources);
}

LevelConstraints buildConstraints(const Points& points, const Points& normals, const ConstraintOptions& options) {
  LevelConstraints out;
  // Surface points (zero-normal ones only if kept).
  std::vector<Eigen::Index> surfaceRows;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    if (!options.dropZeroNormalPoints || normals.row(i).squaredNorm() > 0.0) surfaceRows.push_back(i);
  }
  const NeighborIndex index(points);

  std::vector<Points> blocks;
  std::vector<double> blockTargets;
  Points surface(static_cast<Eigen::Index>(surfaceRows.size()), 3);
  for (std::size_t k = 0; k < surfaceRows.size(); ++k) surface.row(static_cast<Eigen::Index>(k)) = points.row(surfaceRows[k]);
  blocks.push_back(std::move(surface));
  blockTargets.push_back(0.0);
  out.surface = surfaceRows.size();

  for (const double delta : options.offsets) {
    std::size_t candidates = 0;
    blocks.push_back(validCompanions(points, normals, index, delta, options.validityTolerance, options.tangentSideTest,
                                     candidates));
    blockTargets.push_back(delta);
    out.offsetCandidates.push_back(candidates);
    out.offsetKept.push_back(static_cast<std::size_t>(blocks.back().rows()));
  }
  const double d = options.offSurfaceDistance;
  std::vector<int> sides;
  if (options.offSurfaceSide == 2) sides = {-1, 1};
  else if (options.offSurfaceSide != 0) sides = {options.offSurfaceSide};
  for (const int side : sides) {
    std::size_t candidates = 0;
    blocks.push_back(validCompanions(points, normals, index, side * d, options.validityTolerance, options.tangentSideTest,
                                    candidates));
    blockTargets.push_back(side * d);
    out.offSurfaceCandidates += candidates;
    out.offSurfaceKept += static_cast<std::size_t>(blocks.back().rows());
  }

  // Stack in priority order (surface, offsets, off-surface), then drop centres that lie within the merge
  // distance of an earlier kept one.
  Eigen::Index total = 0;
  for (const Points& b : blocks) total += b.rows();
  Points all(total, 3);
  Eigen::VectorXd targets(total);
  std::vector<int> blockOf(static_cast<std::size_t>(total));
  Eigen::Index row = 0;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    all.middleRows(row, blocks[b].rows()) = blocks[b];
    targets.segment(row, blocks[b].rows()).setConstant(blockTargets[b]);
    for (Eigen::Index i = 0; i < blocks[b].rows(); ++i) blockOf[static_cast<std::size_t>(row + i)] = static_cast<int>(b);
    row += blocks[b].rows();
  }
  std::vector<char> keep(static_cast<std::size_t>(total), 1);
  if (options.mergeDistance > 0.0 && total > 0) {
    const NeighborIndex allIndex(all);
    const NeighborLists close = allIndex.radiusSearch(all, options.mergeDistance);
    for (Eigen::Index i = 0; i < total; ++i) {
      const auto ui = static_cast<std::size_t>(i);
      for (auto e = close.offsets[ui]; e < close.offsets[ui + 1]; ++e) {
        const Index j = close.indices[static_cast<std::size_t>(e)];
        if (j < i && keep[static_cast<std::size_t>(j)] != 0) {
          keep[ui] = 0;
          break;
        }
      }
    }
  }
  Eigen::Index kept = 0;
  for (char k : keep) kept += k;
  {
    std::vector<char> isCentre(static_cast<std::size_t>(points.rows()), 0);
    for (std::size_t k = 0; k < surfaceRows.size(); ++k) isCentre[static_cast<std::size_t>(surfaceRows[k])] = keep[k];
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      if (isCentre[static_cast<std::size_t>(i)] == 0) out.surfaceNotCentres.push_back(i);
    }
  }
  out.merged = static_cast<std::size_t>(total - kept);
  out.centres.resize(kept, 3);
  out.targets.resize(kept);
  out.offsetRows.assign(options.offsets.size(), {});
  // Spatial (Morton) order: neighbours in space become neighbours in memory, which keeps SpMV reads of x
  // local and puts each point next to its close offset/off-surface companions (for block preconditioners).
  std::vector<std::pair<std::uint64_t, Eigen::Index>> order;
  order.reserve(static_cast<std::size_t>(kept));
  if (total > 0) {
    const Eigen::Vector3d lo = all.colwise().minCoeff().transpose();
    const double extent = std::max(1e-300, (all.colwise().maxCoeff().transpose() - lo).maxCoeff());
    for (Eigen::Index i = 0; i < total; ++i) {
      if (keep[static_cast<std::size_t>(i)] == 0) continue;
      std::uint64_t key = 0;
      for (int a = 0; a < 3; ++a) {
        const double t = (all(i, a) - lo[a]) / extent * 2097151.0;
        const auto c = static_cast<std::uint64_t>(std::min(2097151.0, std::max(0.0, t)));
        for (int bit = 0; bit < 21; ++bit) key |= ((c >> bit) & 1u) << (3 * bit + a);
      }
      order.emplace_back(key, i);
    }
    std::sort(order.begin(), order.end());
  }
  Eigen::Index r = 0;
  for (const auto& entry : order) {
    const Eigen::Index i = entry.second;
    out.centres.row(r) = all.row(i);
    out.targets[r] = targets[i];
    const int b = blockOf[static_cast<std::size_t>(i)];
    if (b >= 1 && b <= static_cast<int>(options.offsets.size())) out.offsetRows[static_cast<std::size_t>(b - 1)].push_back(r);
    if (b == 0) out.surfaceCentres.emplace_back(surfaceRows[static_cast<std::size_t>(i)], r);
    ++r;
  }
  return out;
}

}  // namespace duplexfit::detail
