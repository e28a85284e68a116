// PointBvh: see point_bvh.hpp. Build: sort by Morton code, split index ranges in halves down to leaves of
// kLeaf points, each node's box the bounds of its points rounded outward to float. Query: depth first,
// nearer child first, a node skipped when its box is farther than the best distance so far.
#include "spatial/point_bvh.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <string>
#include <utility>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "parallel/omp_threads.hpp"
#include "spatial/morton.hpp"
#include "spatial/search_stop.hpp"
#include "spatial/squared_distance.hpp"


namespace duplexfit::detail {

namespace {

/// Points a leaf: 8 measured fastest of 4, 8 and 16 (11.4 µs a query against 13.1 and 11.5).
constexpr std::int32_t kLeaf = 8;
/// Queries a parallel work item.
constexpr std::int64_t kBlock = 512;
/// Relative slack on the squared best distance below which a box is searched: a point whose squared
/// distance rounds differently can still tie the best distance after the square root.
constexpr double kSquaredSlack = 1e-9;

float below(double v) { return std::nextafter(static_cast<float>(v), -std::numeric_limits<float>::infinity()); }
float above(double v) { return std::nextafter(static_cast<float>(v), std::numeric_limits<float>::infinity()); }

}  // namespace

PointBvh::PointBvh(const Points& points) {
  const Eigen::Index n = points.rows();
  if (n > std::numeric_limits<std::int32_t>::max()) {
    throw InvalidArgument("PointBvh: " + std::to_string(n) + " points exceed 2^31 - 1");
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!points.row(i).allFinite()) {
      throw InvalidArgument("PointBvh: point row " + std::to_string(i) + " has a non-finite coordinate");
    }
  }
  if (n == 0) return;
  const MortonGrid grid(points, nullptr, MortonGrid::Box::Cube);
  std::vector<std::pair<std::uint64_t, std::int32_t>> keys(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) keys[static_cast<std::size_t>(i)] = {grid.key(points, i), static_cast<std::int32_t>(i)};
  std::sort(keys.begin(), keys.end());
  points_.resize(3 * static_cast<std::size_t>(n));
  ids_.resize(static_cast<std::size_t>(n));
  for (std::size_t s = 0; s < keys.size(); ++s) {
    ids_[s] = keys[s].second;
    for (int a = 0; a < 3; ++a) points_[3 * s + static_cast<std::size_t>(a)] = points(keys[s].second, a);
  }
  nodes_.reserve(static_cast<std::size_t>(4 * (n / kLeaf + 1)));
  build(0, static_cast<std::int32_t>(n));
}

std::int32_t PointBvh::build(std::int32_t first, std::int32_t last) {
  Node node{};
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::numeric_limits<double>::infinity();
    hi[a] = -std::numeric_limits<double>::infinity();
  }
  for (std::int32_t i = first; i < last; ++i) {
    for (int a = 0; a < 3; ++a) {
      const double v = points_[3 * static_cast<std::size_t>(i) + static_cast<std::size_t>(a)];
      lo[a] = std::min(lo[a], v);
      hi[a] = std::max(hi[a], v);
    }
  }
  // Rounded outward: the float box contains every point exactly.
  for (int a = 0; a < 3; ++a) {
    node.lo[a] = below(lo[a]);
    node.hi[a] = above(hi[a]);
  }
  node.first = first;
  node.last = last;
  node.right = -1;
  const auto me = static_cast<std::int32_t>(nodes_.size());
  nodes_.push_back(node);
  if (last - first > kLeaf) {
    const std::int32_t middle = first + (last - first) / 2;
    build(first, middle);  // the left child is node me + 1
    const std::int32_t right = build(middle, last);
    nodes_[static_cast<std::size_t>(me)].right = right;
  }
  return me;
}

void PointBvh::nearestOther(const Points& queries, const std::vector<Eigen::Index>& exclude, std::vector<double>& distance,
                            std::vector<Eigen::Index>& nearest, Interrupter* interrupter) const {
  const Eigen::Index q = queries.rows();
  if (static_cast<Eigen::Index>(exclude.size()) != q) {
    throw InvalidArgument("PointBvh::nearestOther: " + std::to_string(exclude.size()) + " exclusions for " +
                          std::to_string(q) + " queries");
  }
  for (Eigen::Index i = 0; i < q; ++i) {
    if (!queries.row(i).allFinite()) {
      throw InvalidArgument("PointBvh::nearestOther: query row " + std::to_string(i) + " has a non-finite coordinate");
    }
  }
  distance.assign(static_cast<std::size_t>(q), std::numeric_limits<double>::infinity());
  nearest.assign(static_cast<std::size_t>(q), -1);
  if (q == 0 || nodes_.empty()) return;
  const std::vector<std::uint32_t> order = processingOrder(queries, 4 * kBlock);
  const std::int64_t blocks = (q + kBlock - 1) / kBlock;
  SearchStop stop(interrupter);
  std::atomic<bool> failed{false};
  std::exception_ptr error;

  // The squared distance to a node's box, summed over x, y, z as the point distance is (so that it is
  // never above the squared distance of a point inside: rounding is monotone).
  const auto boxSquared = [](const Node& n, const double* x) {
    double s = 0.0;
    for (int a = 0; a < 3; ++a) {
      const double lo = static_cast<double>(n.lo[a]), hi = static_cast<double>(n.hi[a]);
      const double d = x[a] < lo ? lo - x[a] : (x[a] > hi ? x[a] - hi : 0.0);
      s += d * d;
    }
    return s;
  };

#pragma omp parallel
  {
    const int thread = threadId();
    std::vector<std::int32_t> stack;
    stack.reserve(128);
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t b = 0; b < blocks; ++b) {
      if (failed.load(std::memory_order_relaxed)) continue;
      try {
        if (stop.skip(thread)) continue;
        const std::int64_t end = std::min<std::int64_t>(q, (b + 1) * kBlock);
        for (std::int64_t s = b * kBlock; s < end; ++s) {
          const auto i = order.empty() ? static_cast<Eigen::Index>(s) : static_cast<Eigen::Index>(order[static_cast<std::size_t>(s)]);
          const double x[3] = {queries(i, 0), queries(i, 1), queries(i, 2)};
          const Eigen::Index skip = exclude[static_cast<std::size_t>(i)];
          double best = std::numeric_limits<double>::infinity();  // Euclidean, as knnSearch reports it
          double bound = std::numeric_limits<double>::infinity();  // squared, with slack
          std::int32_t bestId = -1;
          stack.clear();
          stack.push_back(0);
          while (!stack.empty()) {
            const Node& node = nodes_[static_cast<std::size_t>(stack.back())];
            stack.pop_back();
            if (boxSquared(node, x) > bound) continue;
            if (node.right < 0) {
              for (std::int32_t k = node.first; k < node.last; ++k) {
                const double d = std::sqrt(squaredDistance(x, points_.data() + 3 * static_cast<std::size_t>(k)));
                const std::int32_t id = ids_[static_cast<std::size_t>(k)];
                if (id == skip) continue;
                if (d < best || (d == best && id < bestId)) {
                  best = d;
                  bestId = id;
                  bound = std::nextafter(best * best * (1.0 + kSquaredSlack), std::numeric_limits<double>::infinity());
                }
              }
              continue;
            }
            const auto left = static_cast<std::int32_t>(&node - nodes_.data()) + 1;
            const std::int32_t right = node.right;
            const double dl = boxSquared(nodes_[static_cast<std::size_t>(left)], x);
            const double dr = boxSquared(nodes_[static_cast<std::size_t>(right)], x);
            // The nearer child is searched first (pushed last).
            if (dl <= dr) {
              if (dr <= bound) stack.push_back(right);
              if (dl <= bound) stack.push_back(left);
            } else {
              if (dl <= bound) stack.push_back(left);
              if (dr <= bound) stack.push_back(right);
            }
          }
          distance[static_cast<std::size_t>(i)] = best;
          nearest[static_cast<std::size_t>(i)] = bestId;
        }
      } catch (...) {
#pragma omp critical(duplexfit_point_bvh_error)
        if (!error) error = std::current_exception();
        failed.store(true, std::memory_order_relaxed);
      }
    }
  }
  if (error) std::rethrow_exception(error);
  stop.throwIfStopped();
}

void nearestOtherInTree(const NeighborIndex& tree, const Points& queries, const std::vector<Eigen::Index>& exclude,
                        std::vector<double>& distance, std::vector<Eigen::Index>& nearest, Interrupter* interrupter) {
  if (static_cast<Eigen::Index>(exclude.size()) != queries.rows()) {
    throw InvalidArgument("nearestOtherInTree: " + std::to_string(exclude.size()) + " exclusions for " +
                          std::to_string(queries.rows()) + " queries");
  }
  const NeighborLists nn = tree.knnSearch(queries, 2, interrupter);
  distance.assign(exclude.size(), std::numeric_limits<double>::infinity());
  nearest.assign(exclude.size(), -1);
  for (std::size_t k = 0; k < exclude.size(); ++k) {
    for (auto e = nn.offsets[k]; e < nn.offsets[k + 1]; ++e) {
      if (nn.indices[static_cast<std::size_t>(e)] != exclude[k]) {
        distance[k] = nn.distances[static_cast<std::size_t>(e)];
        nearest[k] = nn.indices[static_cast<std::size_t>(e)];
        break;
      }
    }
  }
}

}  // namespace duplexfit::detail
