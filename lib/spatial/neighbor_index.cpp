// NeighborIndex: exact radius and k-nearest queries over a FLANN single k-d tree (header-only use),
// hidden behind a PImpl. Queries run in parallel blocks (OpenMP) with our own result sets, so that
// results are deterministic: sorted by (Euclidean distance, index), ties broken by index.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "duplexfit/neighbors.hpp"

// FLANN's pool allocator may return null in theory, which GCC's -Wnull-dereference reports from the
// inlined tree construction even though the header is a system header.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wnull-dereference"
#include <flann/algorithms/dist.h>
#include <flann/algorithms/kdtree_single_index.h>
#pragma GCC diagnostic pop

#include "duplexfit/error.hpp"
#include "parallel/omp_threads.hpp"
#include "spatial/morton.hpp"
#include "spatial/search_stop.hpp"


namespace duplexfit {

namespace {

using Tree = flann::KDTreeSingleIndex<flann::L2_3D<double>>;

/// Queries per parallel work item: large enough to amortise scheduling, small enough to balance.
constexpr std::int64_t kQueryBlock = 512;

/// Upper bound of the per-thread result reservation (in hits, 16 bytes each).
constexpr double kMaxReserveHits = 64.0 * 1024 * 1024;

/// Capacity of a thread's hit store kept between calls (in hits, 16 bytes each): 1M hits holds a
/// thread's share of a few 10k-query chunks of ~45 results.
constexpr std::size_t kRetainHits = std::size_t{1} << 20;

/// Leaf size of the k-d tree: for radius queries of ~45 results, 24–64 measured ~10% faster than
/// FLANN's default of 10, and larger leaves cost small-radius and k = 1 queries more.
constexpr int kLeafSize = 24;

/// Relative slack on squared bounds handed to FLANN. FLANN prunes and filters on squared distances
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

/// The squared bound to give FLANN so that every point with distance ≤ d passes its tests.
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
class RadiusCollector final : public flann::ResultSet<double> {
 public:
  explicit RadiusCollector(double radius) : radius_(radius), bound_(squaredBound(radius)) {}
  void reset(std::vector<Hit>* out) noexcept { out_ = out; }
  bool full() const override { return true; }
  double worstDist() const override { return bound_; }
  void addPoint(double squared, size_t index) override {
    const double d = std::sqrt(squared);
    if (d < radius_) out_->push_back(Hit{d, static_cast<Index>(index)});
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
class KnnCollector final : public flann::ResultSet<double> {
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
  bool full() const override { return hits_.size() == k_; }
  double worstDist() const override { return bound_; }
  void addPoint(double squared, size_t index) override {
    const Hit h{std::sqrt(squared), static_cast<Index>(index)};
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

/// One empty list a query (a search of an empty set).
NeighborLists noHits(const Points& queries) {
  NeighborLists out;
  out.offsets.assign(static_cast<std::size_t>(queries.rows()) + 1, 0);
  return out;
}

/// FLANN's parameters for an exact search (no check limit, no approximation, results left unsorted).
flann::SearchParams exactSearch() { return flann::SearchParams(flann::FLANN_CHECKS_UNLIMITED, 0.0f, false); }

/// Stops at the first point other than the excluded one with rounded distance < radius: the bound
/// then goes negative, which prunes every branch not yet entered.
class AnyOtherCollector final : public flann::ResultSet<double> {
 public:
  void reset(Index exclude, double radius) noexcept {
    exclude_ = exclude;
    radius_ = radius;
    bound_ = squaredBound(radius);
    found_ = false;
  }
  bool full() const override { return true; }
  double worstDist() const override { return bound_; }
  void addPoint(double squared, size_t index) override {
    if (found_ || static_cast<Index>(index) == exclude_) return;
    const double d = std::sqrt(squared);
    if (!(d < radius_)) return;
    hit_ = Hit{d, static_cast<Index>(index)};
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
  std::vector<double> data;  ///< n×3 row-major copy; FLANN keeps pointers into it
  std::size_t size = 0;
  std::unique_ptr<Tree> tree;  ///< null for an empty set

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
  impl_->data.resize(3 * impl_->size);
  std::memcpy(impl_->data.data(), points.data(), impl_->data.size() * sizeof(double));
  const flann::Matrix<double> matrix(impl_->data.data(), impl_->size, 3);
  impl_->tree = std::make_unique<Tree>(matrix, flann::KDTreeSingleIndexParams(kLeafSize, true));
  impl_->tree->buildIndex();
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
  const Tree& tree = *impl_->tree;
  const flann::SearchParams params = exactSearch();
  return impl_->run(
      queries, [radius] { return RadiusCollector(radius); },
      [&tree, &params, sorted](RadiusCollector& collector, std::size_t, const double* query, std::vector<Hit>& hits) {
        const std::size_t before = hits.size();
        collector.reset(&hits);
        tree.findNeighbors(collector, query, params);
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
  const Tree& tree = *impl_->tree;
  const std::size_t kept = std::min(k, impl_->size);
  const flann::SearchParams params = exactSearch();
  return impl_->run(
      queries, [kept, bound] { return KnnCollector(kept, bound); },
      [&tree, &params](KnnCollector& collector, std::size_t, const double* query, std::vector<Hit>& hits) {
        collector.clear();
        tree.findNeighbors(collector, query, params);
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
  const Tree& tree = *impl_->tree;
  const flann::SearchParams params = exactSearch();
  return impl_->run(
      queries, [] { return AnyOtherCollector(); },
      [&](AnyOtherCollector& collector, std::size_t i, const double* query, std::vector<Hit>& hits) {
        if (!(radius[i] > 0.0)) return;  // no distance is below a radius ≤ 0
        collector.reset(exclude[i], radius[i]);
        tree.findNeighbors(collector, query, params);
        if (collector.found()) hits.push_back(collector.hit());
      },
      interrupter);
}

}  // namespace duplexfit
