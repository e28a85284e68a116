// Normal estimation for unoriented clouds: PCA of k-nearest neighbourhoods (covariances on the device,
// eigenvectors on the host), consistent orientation by propagation along a minimum spanning tree of the
// symmetrised kNN graph (Hoppe et al. 1992), and an outward sign per connected component from the sign
// of the enclosed volume (divergence theorem).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <queue>
#include <sstream>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Eigenvalues>

#include "duplexfit/error.hpp"
#include "duplexfit/timer.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/preprocess.hpp"
#include "preprocess/normals_internal.hpp"
#include "preprocess/preprocess_device.hpp"
#include "spatial/morton.hpp"

namespace duplexfit {

namespace {

using Clock = std::chrono::steady_clock;

/// Components whose |enclosed-volume ratio| is below this have no decidable outward side. The ratio is
/// Σ a_i (p_i − c)·n_i / Σ a_i ‖p_i − c‖: 1 for a sphere, 1.5 r/R for a torus, ≈ 3t/L for a closed plate of
/// thickness t, and only noise for a flat or randomly oriented patch.
constexpr double kAmbiguousRatio = 0.01;

/// With requireOutward, ambiguous components holding at least this share of the points are an error;
/// smaller ones (stray clusters) are only counted.
constexpr double kAmbiguousShare = 0.01;

/// Components of at least this share of the points (and k + 1 points) take part in the nesting test, at
/// most kMaxNestingComponents of them (beyond that the test, quadratic in their number, is skipped), each
/// probed at kNestingSamples points.
constexpr double kNestingShare = 0.005;
constexpr std::size_t kMaxNestingComponents = 64;
constexpr std::size_t kNestingSamples = 5;

/// Weight of the tangent-plane penalty in the graph's edge cost: an edge whose direction leaves the
/// tangent planes of its ends (e.g. across a thin wall, where Hoppe's 1 − |n_i·n_j| alone is 0) costs more.
constexpr double kTangentPenalty = 1.0;

std::string formatPoint(const double* r) {
  std::ostringstream s;
  s << "(" << r[0] << ", " << r[1] << ", " << r[2] << ")";
  return s.str();
}

struct BitsKey {
  std::uint64_t x, y, z;
  bool operator==(const BitsKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct BitsHash {
  std::size_t operator()(const BitsKey& k) const noexcept {
    std::uint64_t h = k.x * 0x9E3779B97F4A7C15ull;
    h ^= (k.y + 0x632BE59BD9B4E019ull) + (h << 6) + (h >> 2);
    h ^= (k.z + 0x85157AF5ull) + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};
std::uint64_t bitsOf(double v) {
  if (v == 0.0) v = 0.0;  // -0 and +0 are the same position
  std::uint64_t b = 0;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

/// 63-bit Morton codes of the selected points on a 2^21 grid over their bounding box.
std::vector<std::uint64_t> mortonKeys(const Points& p, const std::vector<std::size_t>& rows) {
  const detail::MortonGrid grid(p, &rows, detail::MortonGrid::Box::Fitted);
  std::vector<std::uint64_t> key(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) key[i] = grid.key(p, static_cast<Eigen::Index>(rows[i]));
  return key;
}

/// Eigen-decomposition of the whole cloud's covariance: λ ascending (lengths², not normalised).
Eigen::Vector3d globalSpread(const Points& p) {
  const Eigen::RowVector3d mean = p.colwise().mean();
  const Eigen::MatrixXd d = p.rowwise() - mean;
  const Eigen::Matrix3d c = d.transpose() * d / static_cast<double>(p.rows());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(c, Eigen::EigenvaluesOnly);
  return es.eigenvalues();
}

}  // namespace

namespace detail {

PcaNormals pcaNormals(const Device& device, Precision precision, const Points& points, int k, int graphK) {
  PcaNormals out;
  const auto n = static_cast<std::size_t>(points.rows());
  const std::size_t k1 = static_cast<std::size_t>(k) + 1;
  const std::size_t lists = std::min(n, static_cast<std::size_t>(std::max(k, graphK)) + 1);
  out.listSize = lists;

  auto t = Clock::now();
  const NeighborIndex index(points);
  const NeighborLists knn = index.knnSearch(points, static_cast<int>(lists));
  out.neighbors.resize(n * lists);
  std::vector<std::uint32_t> pcaNbr(n * k1);
  out.kthDistance.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto b = static_cast<std::size_t>(knn.offsets[i]);
    if (knn.count(i) != lists) throw Error("pcaNormals: short kNN list");  // cannot happen: n ≥ lists
    for (std::size_t e = 0; e < lists; ++e) out.neighbors[i * lists + e] = static_cast<std::uint32_t>(knn.indices[b + e]);
    for (std::size_t e = 0; e < k1; ++e) pcaNbr[i * k1 + e] = static_cast<std::uint32_t>(knn.indices[b + e]);
    out.kthDistance[i] = knn.distances[b + k1 - 1];
  }
  out.neighborSeconds = secondsSince(t);

  t = Clock::now();
  const Eigen::RowVector3d centre = 0.5 * (points.colwise().minCoeff() + points.colwise().maxCoeff());
  std::vector<double> pos(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) pos[3 * i + static_cast<std::size_t>(c)] = points(static_cast<Eigen::Index>(i), c) - centre[c];
  }
  const std::vector<double> cov = pcaCovariances(device, precision, pos, k1, pcaNbr);
  out.normals = Points::Zero(static_cast<Eigen::Index>(n), 3);
  std::size_t degenerate = 0, nonPlanar = 0;
#pragma omp parallel for schedule(static) reduction(+ : degenerate, nonPlanar)
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(n); ++ii) {
    const double* c = &cov[6 * static_cast<std::size_t>(ii)];
    Eigen::Matrix3d m;
    m << c[0], c[1], c[2], c[1], c[3], c[4], c[2], c[4], c[5];
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(m);
    const Eigen::Vector3d l = es.eigenvalues().cwiseMax(0.0);
    // No plane through the neighbourhood: coincident or collinear neighbours (float sums leave ~1e-7
    // relative noise, hence the tolerance).
    if (!(l[2] > 0.0) || l[1] <= 1e-10 * l[2]) {
      ++degenerate;
      continue;
    }
    if (l[0] > 0.1 * (l[0] + l[1] + l[2])) ++nonPlanar;
    out.normals.row(ii) = es.eigenvectors().col(0).normalized().transpose();
  }
  out.degenerate = degenerate;
  out.nonPlanar = nonPlanar;
  out.pcaSeconds = secondsSince(t);
  return out;
}

}  // namespace detail

NormalResult estimateNormals(const Device& device, const Points& points, const NormalOptions& options,
                             Interrupter* interrupter) {
  const auto start = Clock::now();
  const auto checkpoint = [interrupter](int percent, const char* before) {
    if (interrupter != nullptr && interrupter->wasInterrupted(percent)) {
      throw Cancelled(std::string("estimateNormals: cancelled before ") + before);
    }
  };
  if (options.k < 3) throw InvalidArgument("estimateNormals: k must be at least 3, got " + std::to_string(options.k));
  if (options.graphK < 0) {
    throw InvalidArgument("estimateNormals: graphK must be >= 0 (0: k), got " + std::to_string(options.graphK));
  }
  device.requirePrecision(options.precision);
  const auto n = static_cast<std::size_t>(points.rows());
  for (std::size_t i = 0; i < n; ++i) {
    const double* r = points.data() + 3 * i;
    if (!std::isfinite(r[0]) || !std::isfinite(r[1]) || !std::isfinite(r[2])) {
      throw InvalidArgument("estimateNormals: point " + std::to_string(i) + " has a non-finite coordinate " +
                            formatPoint(r));
    }
  }
  const int k = options.k;
  const int graphK = options.graphK > 0 ? options.graphK : k;
  // Per point: k + 1 neighbours (index and distance), 2·graphK symmetrised graph edges (two indices and a
  // weight), the duplicate map, normals and the k-d tree.
  requireMemory(options.limits, "normals",
                static_cast<double>(n) * (12.0 * (k + 1) + 32.0 * graphK + 200.0),
                std::to_string(n) + " points with k = " + std::to_string(k) + " and graph k = " + std::to_string(graphK),
                "use a smaller --normals-k or --graph-k, or a sparser cloud");

  // Exact duplicates: estimate on the distinct points; every copy takes its first occurrence's normal.
  std::vector<std::uint32_t> rep(n);
  std::vector<std::size_t> firstOf;
  {
    std::unordered_map<BitsKey, std::uint32_t, BitsHash> seen;
    seen.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      const double* r = points.data() + 3 * i;
      const auto [it, inserted] =
          seen.emplace(BitsKey{bitsOf(r[0]), bitsOf(r[1]), bitsOf(r[2])}, static_cast<std::uint32_t>(firstOf.size()));
      if (inserted) firstOf.push_back(i);
      rep[i] = it->second;
    }
  }
  const std::size_t m = firstOf.size();
  const std::size_t duplicates = n - m;
  if (m < static_cast<std::size_t>(k) + 1) {
    throw InvalidArgument("estimateNormals: k = " + std::to_string(k) + " needs at least " + std::to_string(k + 1) +
                          " distinct points, got " + std::to_string(m) +
                          (duplicates > 0 ? " (" + std::to_string(n) + " points, " + std::to_string(duplicates) +
                                                " exact duplicates)"
                                          : std::string()));
  }
  // Work in Morton order: neighbours then sit close in memory, which makes the kNN queries, the graph and
  // the spanning tree several times faster on large clouds stored in random order.
  {
    const std::vector<std::uint64_t> key = mortonKeys(points, firstOf);
    std::vector<std::uint32_t> order(m);
    for (std::size_t i = 0; i < m; ++i) order[i] = static_cast<std::uint32_t>(i);
    std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
      return key[a] < key[b] || (key[a] == key[b] && a < b);
    });
    std::vector<std::uint32_t> slot(m);
    std::vector<std::size_t> sorted(m);
    for (std::size_t i = 0; i < m; ++i) {
      slot[order[i]] = static_cast<std::uint32_t>(i);
      sorted[i] = firstOf[order[i]];
    }
    for (std::size_t i = 0; i < n; ++i) rep[i] = slot[rep[i]];
    firstOf.swap(sorted);
  }
  Points u(static_cast<Eigen::Index>(m), 3);
  for (std::size_t i = 0; i < m; ++i) u.row(static_cast<Eigen::Index>(i)) = points.row(static_cast<Eigen::Index>(firstOf[i]));

  // Whole-cloud shape: a line has no normals, a plane no outward side.
  const Eigen::Vector3d spread = globalSpread(u);
  // Eigenvalues carry rounding of about 1e-16·λ_max, so "zero" is a ratio of 1e-12 (a relative thickness
  // of 1e-6; PLY float coordinates are rounded at 6e-8).
  if (!(spread[1] > 1e-12 * spread[2])) {
    throw InvalidArgument("estimateNormals: all " + std::to_string(m) +
                          " distinct points lie on one line: surface normals are undefined");
  }
  const bool planar = !(spread[0] > 1e-12 * spread[2]);
  if (planar && options.requireOutward) {
    throw InvalidArgument("estimateNormals: all " + std::to_string(m) +
                          " distinct points lie on one plane: the normals can be estimated (they are the plane's) "
                          "but have no outward side (allow unoriented output to get them anyway)");
  }

  checkpoint(0, "the neighbour search");
  detail::PcaNormals pca = detail::pcaNormals(device, options.precision, u, k, graphK);
  checkpoint(50, "the orientation");
  Points& nrm = pca.normals;
  const Points raw = nrm;

  // Orientation graph: the symmetrised kNN graph over the first graphK neighbours.
  auto t = Clock::now();
  const std::size_t gk = std::min<std::size_t>(static_cast<std::size_t>(graphK), m - 1);
  std::vector<std::uint32_t> adjStart(m + 1, 0), adj;
  {
    // Out-edges (kNN) plus in-edges (reverse kNN), counted then filled, then each short list sorted and
    // made unique (no global sort of all edges).
    const auto nbrOf = [&](std::size_t i, std::size_t e) { return pca.neighbors[i * pca.listSize + e]; };
    std::vector<std::uint32_t> degree(m, static_cast<std::uint32_t>(gk));
    for (std::size_t i = 0; i < m; ++i) {
      for (std::size_t e = 1; e <= gk; ++e) ++degree[nbrOf(i, e)];
    }
    std::vector<std::size_t> first(m + 1, 0);
    for (std::size_t i = 0; i < m; ++i) first[i + 1] = first[i] + degree[i];
    std::vector<std::uint32_t> all(first[m]);
    std::vector<std::size_t> fill(first.begin(), first.end() - 1);
    for (std::size_t i = 0; i < m; ++i) {
      for (std::size_t e = 1; e <= gk; ++e) {
        const std::uint32_t j = nbrOf(i, e);
        all[fill[i]++] = j;
        all[fill[j]++] = static_cast<std::uint32_t>(i);
      }
    }
    std::vector<std::uint32_t> unique(m);
#pragma omp parallel for schedule(dynamic, 4096)
    for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(m); ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      auto* b = all.data() + first[i];
      auto* e = all.data() + first[i + 1];
      std::sort(b, e);
      unique[i] = static_cast<std::uint32_t>(std::unique(b, e) - b);
    }
    for (std::size_t i = 0; i < m; ++i) adjStart[i + 1] = adjStart[i] + unique[i];
    adj.resize(adjStart[m]);
    for (std::size_t i = 0; i < m; ++i) {
      std::copy(all.begin() + static_cast<std::ptrdiff_t>(first[i]),
                all.begin() + static_cast<std::ptrdiff_t>(first[i] + unique[i]), adj.begin() + adjStart[i]);
    }
  }

  // Connected components (BFS) and the seed of each: its highest point with a usable normal.
  std::vector<std::uint32_t> comp(m, std::numeric_limits<std::uint32_t>::max());
  std::vector<std::uint32_t> seeds;
  std::vector<std::size_t> compSize;
  {
    std::vector<std::uint32_t> stack;
    for (std::size_t s = 0; s < m; ++s) {
      if (comp[s] != std::numeric_limits<std::uint32_t>::max()) continue;
      const auto c = static_cast<std::uint32_t>(seeds.size());
      std::uint32_t best = static_cast<std::uint32_t>(s);
      bool bestUsable = false;
      std::size_t size = 0;
      comp[s] = c;
      stack.push_back(static_cast<std::uint32_t>(s));
      while (!stack.empty()) {
        const std::uint32_t v = stack.back();
        stack.pop_back();
        ++size;
        const bool usable = nrm.row(v).squaredNorm() > 0.0;
        if ((usable && !bestUsable) || (usable == bestUsable && u(v, 2) > u(best, 2))) {
          best = v;
          bestUsable = usable;
        }
        for (std::uint32_t e = adjStart[v]; e < adjStart[v + 1]; ++e) {
          if (comp[adj[e]] == std::numeric_limits<std::uint32_t>::max()) {
            comp[adj[e]] = c;
            stack.push_back(adj[e]);
          }
        }
      }
      seeds.push_back(best);
      compSize.push_back(size);
    }
  }

  // Prim's minimum spanning tree from each seed; each vertex is oriented to agree with the reference normal
  // of the tree vertex that reached it (its own normal, or for a degenerate vertex its parent's reference).
  Points refNormal = Points::Zero(static_cast<Eigen::Index>(m), 3);
  {
    std::vector<char> done(m, 0);
    std::vector<double> best(m, std::numeric_limits<double>::infinity());  // cheapest known edge into each vertex
    struct Item {
      double cost;
      std::uint32_t to, from;
      bool operator>(const Item& o) const { return cost > o.cost || (cost == o.cost && to > o.to); }
    };
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> heap;
    auto edgeCost = [&](std::uint32_t i, std::uint32_t j) {
      const Eigen::RowVector3d ni = nrm.row(i), nj = nrm.row(j);
      Eigen::RowVector3d e = u.row(j) - u.row(i);
      const double len = e.norm();
      if (len > 0.0) e /= len;
      return 1.0 - std::abs(ni.dot(nj)) + kTangentPenalty * 0.5 * (std::abs(ni.dot(e)) + std::abs(nj.dot(e)));
    };
    auto visit = [&](std::uint32_t v) {
      done[v] = 1;
      for (std::uint32_t e = adjStart[v]; e < adjStart[v + 1]; ++e) {
        const std::uint32_t w = adj[e];
        if (done[w]) continue;
        const double c = edgeCost(v, w);
        if (c < best[w]) {  // only improvements enter the heap (lazy Prim with keys)
          best[w] = c;
          heap.push(Item{c, w, v});
        }
      }
    };
    for (const std::uint32_t s : seeds) {
      if (nrm(s, 2) < 0.0) nrm.row(s) *= -1.0;
      refNormal.row(s) = nrm.row(s).squaredNorm() > 0.0 ? Eigen::RowVector3d(nrm.row(s)) : Eigen::RowVector3d(0, 0, 1);
      visit(s);
      while (!heap.empty()) {
        const Item it = heap.top();
        heap.pop();
        if (done[it.to] || it.cost > best[it.to]) continue;
        const Eigen::RowVector3d ref = refNormal.row(it.from);
        if (nrm.row(it.to).dot(ref) < 0.0) nrm.row(it.to) *= -1.0;
        refNormal.row(it.to) = nrm.row(it.to).squaredNorm() > 0.0 ? Eigen::RowVector3d(nrm.row(it.to)) : ref;
        visit(it.to);
      }
    }
  }

  // Outward sign per component: the enclosed volume (1/3)∮(x − c)·n dA, estimated with the area of each
  // point's kNN disc, must be positive. Unlike a centroid vote this holds for any closed shape (torus,
  // non-star-shaped parts), and it tolerates a few wrongly propagated normals.
  const std::size_t comps = seeds.size();
  std::vector<Eigen::Vector3d> centroid(comps, Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < m; ++i) centroid[comp[i]] += u.row(static_cast<Eigen::Index>(i)).transpose();
  for (std::size_t c = 0; c < comps; ++c) centroid[c] /= static_cast<double>(compSize[c]);
  std::vector<double> vol(comps, 0.0), norm(comps, 0.0);
  for (std::size_t i = 0; i < m; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    const double a = pca.kthDistance[i] * pca.kthDistance[i];
    const Eigen::Vector3d d = u.row(ii).transpose() - centroid[comp[i]];
    vol[comp[i]] += a * d.dot(nrm.row(ii).transpose());
    norm[comp[i]] += a * d.norm();
  }
  std::size_t ambiguous = 0, flippedComponents = 0;
  double minRatio = std::numeric_limits<double>::infinity();
  std::vector<char> flipComp(comps, 0);
  for (std::size_t c = 0; c < comps; ++c) {
    const double ratio = norm[c] > 0.0 ? vol[c] / norm[c] : 0.0;
    if (planar || std::abs(ratio) < kAmbiguousRatio) {
      ++ambiguous;
      if (options.requireOutward && static_cast<double>(compSize[c]) >= kAmbiguousShare * static_cast<double>(m)) {
        std::ostringstream msg;
        msg << "estimateNormals: " << (comps == 1 ? "the cloud" : "component " + std::to_string(c) + " of " + std::to_string(comps))
            << " (" << compSize[c] << " points around " << centroid[c].transpose()
            << ") encloses no volume (ratio " << ratio
            << "): it is flat or open, so its normals can be made consistent but not outward "
               "(allow unoriented output to get them anyway)";
        throw InvalidArgument(msg.str());
      }
      continue;
    }
    minRatio = std::min(minRatio, std::abs(ratio));
    if (ratio < 0.0) {
      flipComp[c] = 1;
      ++flippedComponents;
    }
  }
  for (std::size_t i = 0; i < m; ++i) {
    if (flipComp[comp[i]]) nrm.row(static_cast<Eigen::Index>(i)) *= -1.0;
  }

  // Nesting: a closed component inside another one (the inner wall of a hollow shell) bounds a cavity, so
  // its outward side faces its own centroid. Each major component is tested at a few of its points with
  // the generalised winding number of every other major component, w_A(x) = (1/4π) Σ a_i (p_i − x)·n_i /
  // ‖p_i − x‖³ (≈ 1 inside A, 0 outside; a_i = π r_k²/(k + 1)); an odd nesting depth flips the component.
  std::size_t nested = 0;
  {
    std::vector<std::size_t> major;
    for (std::size_t c = 0; c < comps; ++c) {
      if (compSize[c] >= static_cast<std::size_t>(k) + 1 &&
          static_cast<double>(compSize[c]) >= kNestingShare * static_cast<double>(m)) {
        major.push_back(c);
      }
    }
    if (major.size() >= 2 && major.size() <= kMaxNestingComponents) {
      std::vector<std::vector<std::uint32_t>> members(comps);
      for (std::size_t i = 0; i < m; ++i) members[comp[i]].push_back(static_cast<std::uint32_t>(i));
      std::vector<char> flipNested(comps, 0);
      for (const std::size_t b : major) {
        const std::vector<std::uint32_t>& mb = members[b];
        int depth = 0;
        for (const std::size_t a : major) {
          if (a == b) continue;
          int inside = 0;
          for (std::size_t sIdx = 0; sIdx < kNestingSamples; ++sIdx) {
            const Eigen::RowVector3d x = u.row(mb[(sIdx * mb.size()) / kNestingSamples]);
            double w = 0.0;
#pragma omp parallel for reduction(+ : w) schedule(static)
            for (std::ptrdiff_t e = 0; e < static_cast<std::ptrdiff_t>(members[a].size()); ++e) {
              const std::uint32_t i = members[a][static_cast<std::size_t>(e)];
              const Eigen::RowVector3d d = u.row(i) - x;
              const double r2 = d.squaredNorm();
              const double area = M_PI * pca.kthDistance[i] * pca.kthDistance[i] / (k + 1);
              w += area * d.dot(nrm.row(i)) / (r2 * std::sqrt(r2));
            }
            inside += w / (4.0 * M_PI) > 0.5 ? 1 : 0;
          }
          depth += 2 * inside > static_cast<int>(kNestingSamples) ? 1 : 0;
        }
        if (depth % 2 == 1) flipNested[b] = 1;
      }
      for (std::size_t c = 0; c < comps; ++c) nested += flipNested[c] ? 1 : 0;
      for (std::size_t i = 0; i < m; ++i) {
        if (flipNested[comp[i]]) nrm.row(static_cast<Eigen::Index>(i)) *= -1.0;
      }
    }
  }
  std::size_t flipped = 0;
  for (std::size_t i = 0; i < m; ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    if (nrm.row(ii).dot(raw.row(ii)) < 0.0) ++flipped;
  }
  const double orientSeconds = secondsSince(t);

  Points outNormals(static_cast<Eigen::Index>(n), 3);
  for (std::size_t i = 0; i < n; ++i) outNormals.row(static_cast<Eigen::Index>(i)) = nrm.row(rep[i]);
  NormalResult result{PointSet(points, outNormals), NormalReport{}};
  {
    NormalReport& r = result.report;
    r.device = device.info().spec;
    r.precision = options.precision;
    r.points = n;
    r.duplicates = duplicates;
    r.k = k;
    r.graphK = static_cast<int>(gk);
    r.components = comps;
    r.ambiguousComponents = ambiguous;
    r.flippedComponents = flippedComponents;
    r.nestedComponents = nested;
    r.flipped = flipped;
    r.degenerate = pca.degenerate;
    r.nonPlanar = pca.nonPlanar;
    r.minVolumeRatio = std::isfinite(minRatio) ? minRatio : 0.0;
    r.neighborSeconds = pca.neighborSeconds;
    r.pcaSeconds = pca.pcaSeconds;
    r.orientSeconds = orientSeconds;
    r.seconds = secondsSince(start);
  }
  return result;
}

}  // namespace duplexfit
