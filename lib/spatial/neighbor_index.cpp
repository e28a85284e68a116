// NeighborIndex: exact radius and k-nearest queries over a k-d tree of our own (3D only, result sets as
// template parameters: no virtual call per point or node), hidden behind a PImpl. Queries run in parallel
// blocks (OpenMP), so that results are deterministic: sorted by (Euclidean distance, index), ties broken by
// index.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "duplexfit/neighbors.hpp"
#include "duplexfit/error.hpp"
#include "parallel/omp_threads.hpp"
#include "spatial/morton.hpp"
#include "spatial/search_stop.hpp"
#include "spatial/squared_distance.hpp"

namespace duplexfit {

namespace {

/// Queries per parallel work item: large enough to amortise scheduling, small enough to balance.
constexpr std::int64_t kQueryBlock = 512;

/// Upper bound of the per-thread result reservation (in hits, 16 bytes each).
constexpr double kMaxReserveHits = 64.0 * 1024 * 1024;

/// Capacity of a thread's hit store kept between calls (in hits, 16 bytes each): 1M hits holds a
/// thread's share of a few 10k-query chunks of ~45 results.
constexpr std::size_t kRetainHits = std::size_t{1} << 20;

/// Leaf size of the k-d tree (points): for radius queries of ~45 results, 24–64 measured ~10% faster than
/// 10 (FLANN's default, when this index was FLANN's), and larger leaves cost small-radius and k = 1 queries
/// more; 12 to 32 take the same time on fandisk_550k's queries.
constexpr std::uint32_t kLeafSize = 24;

/// Relative slack on the squared bounds of the result sets. The tree prunes and filters on squared distances
/// (‖p − q‖² < bound) while we decide on the rounded Euclidean distance; the slack makes sure no
/// candidate that passes our test is pruned by rounding in the tree's incremental box distances.
constexpr double kSquaredSlack = 1e-9;

/// A neighbour candidate: Euclidean distance and point index.
struct Hit {
  double distance;
  Index index;
};

inline bool hitLess(const Hit& a, const Hit& b) noexcept {
  return a.distance < b.distance || (a.distance == b.distance && a.index < b.index);
}

/// The squared bound to give the tree so that every point with distance ≤ d passes its tests.
inline double squaredBound(double d) noexcept {
  return std::nextafter(d * d * (1.0 + kSquaredSlack), std::numeric_limits<double>::infinity());
}

void checkFinite(const Points& points, const char* what) {
  const Eigen::Index n = points.rows();
  const double* p = points.data();
  for (Eigen::Index i = 0; i < n; ++i) {
    const double* r = p + 3 * i;
    if (!std::isfinite(r[0]) || !std::isfinite(r[1]) || !std::isfinite(r[2])) {
      throw InvalidArgument(std::string("NeighborIndex: ") + what + " row " + std::to_string(i) +
                            " has a non-finite coordinate (" + std::to_string(r[0]) + ", " +
                            std::to_string(r[1]) + ", " + std::to_string(r[2]) + ")");
    }
  }
}

/// Collects every point with rounded Euclidean distance < radius (strict), unsorted.
class RadiusCollector {
 public:
  explicit RadiusCollector(double radius) : radius_(radius), bound_(squaredBound(radius)) {}
  void reset(std::vector<Hit>* out) noexcept { out_ = out; }
  double worstDist() const { return bound_; }
  void addPoint(double squared, Index index) {
    const double d = std::sqrt(squared);
    if (d < radius_) out_->push_back(Hit{d, index});
  }

 private:
  double radius_;
  double bound_;
  std::vector<Hit>* out_ = nullptr;
};

/// Keeps the k smallest (distance, index) pairs: ties at the k-th place go to the smaller index, so the
/// result does not depend on the tree's visiting order. For k ≤ kSortedK the hits are kept sorted and a new
/// one is inserted by shifting the larger ones up (1.3x faster than a heap's sifts for the fit's k = 12–13
/// searches, docs/benchmarks.md); larger k keep a max-heap.
class KnnCollector {
 public:
  static constexpr std::size_t kSortedK = 32;
  /// `initialBound`: squared distance beyond which no point is taken (the search prunes there).
  explicit KnnCollector(std::size_t k, double initialBound = std::numeric_limits<double>::max())
      : k_(k), initialBound_(initialBound), bound_(initialBound) {
    hits_.reserve(k);
  }
  void clear() noexcept {
    hits_.clear();
    bound_ = initialBound_;
  }
  double worstDist() const { return bound_; }
  void addPoint(double squared, Index index) {
    const Hit h{std::sqrt(squared), index};
    if (k_ <= kSortedK) {
      std::size_t j = hits_.size();
      if (j == k_) {
        if (!hitLess(h, hits_[j - 1])) return;
        --j;  // the largest drops out
      } else {
        hits_.push_back(h);  // room; overwritten below
      }
      for (; j > 0 && hitLess(h, hits_[j - 1]); --j) hits_[j] = hits_[j - 1];
      hits_[j] = h;
      if (hits_.size() == k_) bound_ = squaredBound(hits_.back().distance);
      return;
    }
    if (hits_.size() < k_) {
      hits_.push_back(h);
      std::push_heap(hits_.begin(), hits_.end(), hitLess);
    } else if (hitLess(h, hits_.front())) {
      std::pop_heap(hits_.begin(), hits_.end(), hitLess);
      hits_.back() = h;
      std::push_heap(hits_.begin(), hits_.end(), hitLess);
    } else {
      return;
    }
    if (hits_.size() == k_) bound_ = squaredBound(hits_.front().distance);
  }
  /// Sorts the kept hits ascending (the heap's) and appends them to out.
  void appendSorted(std::vector<Hit>& out) {
    if (k_ > kSortedK) std::sort_heap(hits_.begin(), hits_.end(), hitLess);
    out.insert(out.end(), hits_.begin(), hits_.end());
  }

 private:
  std::size_t k_;
  std::vector<Hit> hits_;
  double initialBound_;
  double bound_;
};

/// The k-d tree: median splits on the axis of the largest extent down to leaves of at most kLeafSize points,
/// the points copied in leaf order. The search is the classic one for exact nearest neighbours (Arya and
/// Mount's incremental distance to the cell, as FLANN's single-tree index does it): the nearer child first,
/// the other only when the squared distance to its cell does not exceed the result set's bound. The result
/// set is a template parameter, so neither the per-point test nor the bound is a virtual call (FLANN's
/// ResultSet made both virtual: 15% of fandisk_550k's fit samples were its search and its callbacks).
/// Squared distances are detail::squaredDistance's (summed as FLANN's L2_3D did), so every distance is the
/// one the FLANN index gave (the fields and meshes of fandisk_550k, wheel_118k and wheel_29k
/// came out byte for byte the same).
class KdTree {
 public:
  KdTree(const double* xyz, std::size_t n) {
    if (n == 0) return;
    // The points with their rows, sorted in place by the splits (the comparisons read the coordinates
    // directly, not through an index).
    std::vector<Slot> slots(n);
    for (int c = 0; c < 3; ++c) {
      lo_[c] = HUGE_VAL;
      hi_[c] = -HUGE_VAL;
    }
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t c = 0; c < 3; ++c) {
        slots[i].p[c] = xyz[3 * i + c];
        lo_[c] = std::min(lo_[c], slots[i].p[c]);
        hi_[c] = std::max(hi_[c], slots[i].p[c]);
      }
      slots[i].id = static_cast<Index>(i);
    }
    nodes_.reserve(2 * (n / (kLeafSize / 2) + 1));
    build(slots.data(), 0, static_cast<std::uint32_t>(n), lo_, hi_);
    pts_.resize(3 * n);
    ids_.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      for (std::size_t c = 0; c < 3; ++c) pts_[3 * k + c] = slots[k].p[c];
      ids_[k] = slots[k].id;
    }
  }

  /// Offers every point that may belong to the result set c (c.worstDist(): its squared bound, read before
  /// each point and each far child; c.addPoint: a point with its squared distance below that bound).
  template <typename Collector>
  void search(const double* q, Collector& c) const {
    if (nodes_.empty()) return;
    double dists[3] = {0.0, 0.0, 0.0};
    double distsq = 0.0;
    for (int d = 0; d < 3; ++d) {
      if (q[d] < lo_[d]) {
        dists[d] = (q[d] - lo_[d]) * (q[d] - lo_[d]);
        distsq += dists[d];
      }
      if (q[d] > hi_[d]) {
        dists[d] = (q[d] - hi_[d]) * (q[d] - hi_[d]);
        distsq += dists[d];
      }
    }
    searchNode(c, q, 0, distsq, dists);
  }

 private:
  struct Node {
    double low;           ///< inner: the largest coordinate on `axis` of the left part
    double high;          ///< inner: the smallest coordinate on `axis` of the right part
    std::int32_t axis;    ///< −1: a leaf
    std::uint32_t first;  ///< inner: the right child (the left one is the next node); leaf: its first slot
    std::uint32_t last;   ///< leaf: one past its last slot
  };

  /// A point and its input row, during the build.
  struct Slot {
    double p[3];
    Index id;
  };

  /// The subtree of slots [begin, end) (their box lo–hi) at nodes_.size().
  void build(Slot* slots, std::uint32_t begin, std::uint32_t end, const double* lo, const double* hi) {
    const std::size_t self = nodes_.size();
    nodes_.push_back(Node{0.0, 0.0, -1, begin, end});
    int axis = 0;
    for (int c = 1; c < 3; ++c) {
      if (hi[c] - lo[c] > hi[axis] - lo[axis]) axis = c;
    }
    // A leaf: few points, or all of them at one place (duplicates do not split).
    if (end - begin <= kLeafSize || !(hi[axis] > lo[axis])) return;
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(slots + begin, slots + mid, slots + end, [axis](const Slot& a, const Slot& b) {
      return a.p[axis] < b.p[axis] || (a.p[axis] == b.p[axis] && a.id < b.id);
    });
    // The two parts' boxes (for their own splits) and the gap between them on `axis`.
    double llo[3], lhi[3], rlo[3], rhi[3];
    for (int c = 0; c < 3; ++c) {
      llo[c] = rlo[c] = HUGE_VAL;
      lhi[c] = rhi[c] = -HUGE_VAL;
    }
    for (std::uint32_t k = begin; k < end; ++k) {
      const double* p = slots[k].p;
      double* blo = k < mid ? llo : rlo;
      double* bhi = k < mid ? lhi : rhi;
      for (int c = 0; c < 3; ++c) {
        blo[c] = std::min(blo[c], p[c]);
        bhi[c] = std::max(bhi[c], p[c]);
      }
    }
    build(slots, begin, mid, llo, lhi);
    const auto right = static_cast<std::uint32_t>(nodes_.size());
    build(slots, mid, end, rlo, rhi);
    nodes_[self] = Node{lhi[axis], rlo[axis], axis, right, 0};
  }

  template <typename Collector>
  void searchNode(Collector& c, const double* q, std::uint32_t node, double mindistsq, double* dists) const {
    const Node& n = nodes_[node];
    if (n.axis < 0) {
      // The bound is read again after every point taken (a k-nearest set's shrinks as it fills; FLANN read it
      // once a leaf): the same points end in the set, fewer are offered to it.
      for (std::uint32_t s = n.first; s < n.last; ++s) {
        const double r = detail::squaredDistance(q, pts_.data() + 3 * static_cast<std::size_t>(s));
        if (r < c.worstDist()) c.addPoint(r, ids_[s]);
      }
      return;
    }
    const double val = q[n.axis];
    const double diff1 = val - n.low, diff2 = val - n.high;
    std::uint32_t best, other;
    double cut;
    if (diff1 + diff2 < 0.0) {
      best = node + 1;
      other = n.first;
      cut = diff2 * diff2;
    } else {
      best = n.first;
      other = node + 1;
      cut = diff1 * diff1;
    }
    searchNode(c, q, best, mindistsq, dists);
    const double dst = dists[n.axis];
    mindistsq = mindistsq + cut - dst;
    dists[n.axis] = cut;
    if (mindistsq <= c.worstDist()) searchNode(c, q, other, mindistsq, dists);
    dists[n.axis] = dst;
  }

  std::vector<Node> nodes_;
  std::vector<double> pts_;  ///< x y z a slot, in leaf order
  std::vector<Index> ids_;   ///< the input row of each slot
  double lo_[3] = {0.0, 0.0, 0.0}, hi_[3] = {0.0, 0.0, 0.0};
};

/// One empty list a query (a search of an empty set).
NeighborLists noHits(const Points& queries) {
  NeighborLists out;
  out.offsets.assign(static_cast<std::size_t>(queries.rows()) + 1, 0);
  return out;
}

/// Stops at the first point other than the excluded one with rounded distance < radius: the bound
/// then goes negative, which prunes every branch not yet entered.
class AnyOtherCollector {
 public:
  void reset(Index exclude, double radius) noexcept {
    exclude_ = exclude;
    radius_ = radius;
    bound_ = squaredBound(radius);
    found_ = false;
  }
  double worstDist() const { return bound_; }
  void addPoint(double squared, Index index) {
    if (found_ || index == exclude_) return;
    const double d = std::sqrt(squared);
    if (!(d < radius_)) return;
    hit_ = Hit{d, index};
    found_ = true;
    bound_ = -1.0;
  }
  bool found() const noexcept { return found_; }
  const Hit& hit() const noexcept { return hit_; }

 private:
  Index exclude_ = -1;
  double radius_ = 0.0;
  double bound_ = 0.0;
  bool found_ = false;
  Hit hit_{};
};

using detail::maxThreads;
using detail::teamSize;
using detail::threadId;

/// Sorts one query's hits by (distance, index). Lists are short (tens of entries), where an
/// insertion sort beats std::sort by ~40% (fewer mispredicted branches); long lists use std::sort.
void sortHits(Hit* first, Hit* last) {
  if (last - first > 64) {
    std::sort(first, last, hitLess);
    return;
  }
  for (Hit* i = first + (first != last); i < last; ++i) {
    const Hit h = *i;
    Hit* j = i;
    for (; j > first && hitLess(h, j[-1]); --j) *j = j[-1];
    *j = h;
  }
}

}  // namespace

namespace {

/// This thread's store of hits, reused across calls (see kRetainHits).
std::vector<Hit>& threadStore() {
  thread_local std::vector<Hit> store;
  return store;
}

/// Records the first exception thrown inside an OpenMP region, to rethrow it outside.
class ErrorSlot {
 public:
  void capture() noexcept {
#pragma omp critical(duplexfit_neighbors_error)
    if (!error_) error_ = std::current_exception();
  }
  bool failed() const noexcept {
    bool result = false;
#pragma omp critical(duplexfit_neighbors_error)
    result = static_cast<bool>(error_);
    return result;
  }
  void rethrow() const {
    if (error_) std::rethrow_exception(error_);
  }

 private:
  std::exception_ptr error_;
};

}  // namespace

struct NeighborIndex::Impl {
  std::size_t size = 0;
  std::unique_ptr<KdTree> tree;  ///< null for an empty set

  /// Runs searchOne(state, i, query, hits) for every query (row i, its coordinates at `query`) in parallel
  /// blocks and returns the lists; each thread owns a state from makeState(), and searchOne appends one
  /// query's sorted hits;
  /// `interrupter` can stop it (detail::SearchStop: run then throws Cancelled).
  template <typename MakeState, typename SearchOne>
  NeighborLists run(const Points& queries, MakeState makeState, SearchOne searchOne, Interrupter* interrupter) const;
};

template <typename MakeState, typename SearchOne>
NeighborLists NeighborIndex::Impl::run(const Points& queries, MakeState makeState, SearchOne searchOne,
                                       Interrupter* interrupter) const {
  NeighborLists out;
  const auto q = static_cast<std::int64_t>(queries.rows());
  out.offsets.assign(static_cast<std::size_t>(q) + 1, 0);
  if (q == 0 || size == 0) return out;

  // Queries are searched in Morton order, so that consecutive queries walk the same part of the
  // tree (at 3M points ~1.5x faster than an incoherent input order once the tree outgrows the
  // cache); results are still returned in input order.
  const std::vector<std::uint32_t> order = detail::processingOrder(queries, 4 * kQueryBlock);
  const auto queryAt = [&order](std::int64_t s) {
    return order.empty() ? s : static_cast<std::int64_t>(order[static_cast<std::size_t>(s)]);
  };

  // One parallel region: pass 1 searches blocks of queries (in processing order, handed out
  // dynamically), each thread appending hits to its own store and counts to offsets[i + 1]; one
  // thread then sums the counts and sizes the output; pass 2 copies every query's hits from the
  // store that holds them to their place in the flat arrays.
  const std::int64_t blocks = (q + kQueryBlock - 1) / kQueryBlock;
  struct BlockSource {
    int thread;
    std::size_t begin;
  };
  std::vector<BlockSource> source(static_cast<std::size_t>(blocks));
  std::vector<const std::vector<Hit>*> stores(static_cast<std::size_t>(maxThreads()), nullptr);
  const double* qp = queries.data();
  ErrorSlot error;
  detail::SearchStop stop(interrupter);
#pragma omp parallel
  {
    const int t = threadId();
    std::vector<Hit>& hits = threadStore();
    hits.clear();
    stores[static_cast<std::size_t>(t)] = &hits;
    std::optional<decltype(makeState())> state;
    try {
      state.emplace(makeState());
    } catch (...) {
      error.capture();
    }
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t b = 0; b < blocks; ++b) {
      if (!state) continue;
      try {
        if (stop.skip(t)) continue;
        const bool firstBlock = hits.empty();
        source[static_cast<std::size_t>(b)] = BlockSource{t, hits.size()};
        const std::int64_t begin = b * kQueryBlock;
        const std::int64_t end = std::min(q, begin + kQueryBlock);
        for (std::int64_t s = begin; s < end; ++s) {
          const std::int64_t i = queryAt(s);
          const std::size_t before = hits.size();
          searchOne(*state, static_cast<std::size_t>(i), qp + 3 * i, hits);
          out.offsets[static_cast<std::size_t>(i) + 1] =
              static_cast<std::int64_t>(hits.size() - before);
        }
        if (firstBlock) {
          // Reserve this thread's share once, extrapolated from its first block with a margin and
          // capped (avoids repeated reallocation; capacity that is never written stays virtual).
          const double perQuery =
              static_cast<double>(hits.size()) / static_cast<double>(end - begin);
          const double share = static_cast<double>(q) / static_cast<double>(teamSize());
          const double want = std::min(1.25 * perQuery * share, kMaxReserveHits);
          hits.reserve(std::max(hits.size(), static_cast<std::size_t>(want)));
        }
      } catch (...) {
        error.capture();
      }
    }

#pragma omp single
    {
      try {
        if (!error.failed() && !stop.stopped()) {
          for (std::size_t i = 1; i < out.offsets.size(); ++i) out.offsets[i] += out.offsets[i - 1];
          const auto total = static_cast<std::size_t>(out.offsets.back());
          out.indices.resize(total);
          out.distances.resize(total);
        }
      } catch (...) {
        error.capture();
      }
    }

    // The same answer in every thread after the barrier of single.
    if (!error.failed() && !stop.stopped()) {
#pragma omp for schedule(dynamic, 4)
      for (std::int64_t b = 0; b < blocks; ++b) {
        const BlockSource& src = source[static_cast<std::size_t>(b)];
        const Hit* from = stores[static_cast<std::size_t>(src.thread)]->data() + src.begin;
        const std::int64_t end = std::min(q, (b + 1) * kQueryBlock);
        for (std::int64_t s = b * kQueryBlock; s < end; ++s) {
          const auto i = static_cast<std::size_t>(queryAt(s));
          const auto first = static_cast<std::size_t>(out.offsets[i]);
          const auto count = static_cast<std::size_t>(out.offsets[i + 1]) - first;
          Index* idx = out.indices.data() + first;
          double* dist = out.distances.data() + first;
          for (std::size_t j = 0; j < count; ++j) {
            idx[j] = from[j].index;
            dist[j] = from[j].distance;
          }
          from += count;
        }
      }
    }
    // Keep a moderate store for the next call (repeated chunked searches then reuse warm memory
    // instead of faulting in fresh pages every time); give back anything larger.
    if (hits.capacity() > kRetainHits) std::vector<Hit>().swap(hits);
  }
  error.rethrow();
  stop.throwIfStopped();
  return out;
}

NeighborIndex::NeighborIndex(const Points& points) : impl_(std::make_unique<Impl>()) {
  if (points.rows() > std::numeric_limits<Index>::max()) {
    throw InvalidArgument("NeighborIndex: " + std::to_string(points.rows()) +
                          " points exceed the Index range (2^31 - 1)");
  }
  checkFinite(points, "point");
  impl_->size = static_cast<std::size_t>(points.rows());
  if (impl_->size == 0) return;
  impl_->tree = std::make_unique<KdTree>(points.data(), impl_->size);
}

NeighborIndex::NeighborIndex(NeighborIndex&&) noexcept = default;
NeighborIndex& NeighborIndex::operator=(NeighborIndex&&) noexcept = default;
NeighborIndex::~NeighborIndex() = default;

std::size_t NeighborIndex::size() const noexcept { return impl_ ? impl_->size : 0; }

NeighborLists NeighborIndex::radiusSearch(const Points& queries, double radius, Interrupter* interrupter) const {
  return radiusImpl(queries, radius, interrupter, true);
}

NeighborLists NeighborIndex::radiusSearchUnsorted(const Points& queries, double radius, Interrupter* interrupter) const {
  return radiusImpl(queries, radius, interrupter, false);
}

NeighborLists NeighborIndex::radiusImpl(const Points& queries, double radius, Interrupter* interrupter, bool sorted) const {
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    throw InvalidArgument("NeighborIndex::radiusSearch: radius must be positive and finite, got " +
                          std::to_string(radius));
  }
  checkFinite(queries, "query");
  if (size() == 0) return noHits(queries);
  const KdTree& tree = *impl_->tree;
  return impl_->run(
      queries, [radius] { return RadiusCollector(radius); },
      [&tree, sorted](RadiusCollector& collector, std::size_t, const double* query, std::vector<Hit>& hits) {
        const std::size_t before = hits.size();
        collector.reset(&hits);
        tree.search(query, collector);
        if (sorted) sortHits(hits.data() + before, hits.data() + hits.size());
      },
      interrupter);
}

NeighborLists NeighborIndex::knnSearch(const Points& queries, int k, Interrupter* interrupter) const {
  if (k <= 0) {
    throw InvalidArgument("NeighborIndex::knnSearch: k must be positive, got " + std::to_string(k));
  }
  return knnImpl(queries, static_cast<std::size_t>(k), std::numeric_limits<double>::max(), interrupter);
}

NeighborLists NeighborIndex::nearestWithin(const Points& queries, double radius, Interrupter* interrupter) const {
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    throw InvalidArgument("NeighborIndex::nearestWithin: radius must be positive and finite, got " + std::to_string(radius));
  }
  return knnImpl(queries, 1, squaredBound(radius), interrupter);
}

NeighborLists NeighborIndex::knnImpl(const Points& queries, std::size_t k, double bound, Interrupter* interrupter) const {
  checkFinite(queries, "query");
  if (size() == 0) return noHits(queries);
  const KdTree& tree = *impl_->tree;
  const std::size_t kept = std::min(k, impl_->size);
  return impl_->run(
      queries, [kept, bound] { return KnnCollector(kept, bound); },
      [&tree](KnnCollector& collector, std::size_t, const double* query, std::vector<Hit>& hits) {
        collector.clear();
        tree.search(query, collector);
        collector.appendSorted(hits);
      },
      interrupter);
}

NeighborLists NeighborIndex::anyOtherWithin(const Points& queries, const std::vector<Index>& exclude,
                                           const std::vector<double>& radius, Interrupter* interrupter) const {
  if (exclude.size() != static_cast<std::size_t>(queries.rows()) || radius.size() != exclude.size()) {
    throw InvalidArgument("NeighborIndex::anyOtherWithin: " + std::to_string(queries.rows()) + " queries, " +
                          std::to_string(exclude.size()) + " exclusions and " + std::to_string(radius.size()) +
                          " radii");
  }
  for (std::size_t i = 0; i < radius.size(); ++i) {
    if (!std::isfinite(radius[i])) {
      throw InvalidArgument("NeighborIndex::anyOtherWithin: radius " + std::to_string(i) + " is not finite");
    }
  }
  checkFinite(queries, "query");
  if (size() == 0) return noHits(queries);
  const KdTree& tree = *impl_->tree;
  return impl_->run(
      queries, [] { return AnyOtherCollector(); },
      [&](AnyOtherCollector& collector, std::size_t i, const double* query, std::vector<Hit>& hits) {
        if (!(radius[i] > 0.0)) return;  // no distance is below a radius ≤ 0
        collector.reset(exclude[i], radius[i]);
        tree.search(query, collector);
        if (collector.found()) hits.push_back(collector.hit());
      },
      interrupter);
}

}  // namespace duplexfit
