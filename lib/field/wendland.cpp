// Assembly of the level system Φ + λI (docs/method.md §5) as a CSR matrix: a radius search with the
// support σ gives each row's neighbours, which are sorted by column and mapped through φ(d/σ). The
// search runs on a grid of σ cells over the centres (spatial/cell_grid.hpp), or on a k-d tree
// (NeighborIndex) where that grid's table would be too large; both find the same neighbours at the same
// distances, so the matrix is the same. Rows are processed in chunks so that the neighbour lists never
// exist for all rows at once.
#include "duplexfit/wendland.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "field/wendland_detail.hpp"
#include "parallel/omp_threads.hpp"
#include "spatial/cell_grid.hpp"
#include "spatial/search_stop.hpp"


namespace duplexfit {

namespace {

/// Rows per radius-search chunk: bounds the temporary neighbour lists (~28 bytes per non-zero) and
/// keeps them small enough for the search to reuse its buffers from one chunk to the next.
constexpr Index kChunkRows = Index{1} << 15;

/// Rows sampled to estimate the total non-zero count before reserving the CSR arrays.
constexpr Index kSampleRows = 1024;

constexpr std::int64_t kMaxNonZeros = std::numeric_limits<Index>::max();

struct Entry {
  Index col;
  double distance;
};

/// Sorts a row's entries by column (key(entry)): an insertion sort for the usual tens of entries (fewer
/// mispredicted branches than std::sort), std::sort for long rows.
template <typename T, typename Key>
void sortByColumn(T* first, T* last, Key key) {
  if (last - first > 64) {
    std::sort(first, last, [&key](const T& x, const T& y) { return key(x) < key(y); });
    return;
  }
  for (T* i = first + (first != last); i < last; ++i) {
    const T e = *i;
    T* j = i;
    for (; j > first && key(e) < key(j[-1]); --j) *j = j[-1];
    *j = e;
  }
}

void checkCentres(const Points& centres) {
  for (Eigen::Index i = 0; i < centres.rows(); ++i) {
    if (!centres.row(i).allFinite()) {
      throw InvalidArgument("assembleWendland: centre row " + std::to_string(i) +
                            " has a non-finite coordinate");
    }
  }
}

/// An n × n matrix with no entries yet (row pointers all 0), in the arrays of `storage` (when not null:
/// their capacity is taken over and `storage` is left empty).
CsrMatrix noEntries(Index n, CsrMatrix* storage) {
  CsrMatrix a;
  if (storage != nullptr) {
    a.rowPtr = std::move(storage->rowPtr);
    a.colIdx = std::move(storage->colIdx);
    a.values = std::move(storage->values);
    *storage = CsrMatrix{};
    a.colIdx.clear();
    a.values.clear();
  }
  a.rows = n;
  a.cols = n;
  a.rowPtr.assign(static_cast<std::size_t>(n) + 1, 0);
  return a;
}

/// Reserves the CSR arrays once for the non-zeros expected from a sample of evenly spaced rows (with a
/// margin; unused capacity stays virtual memory, never touched), after the caller's check.
/// hitsOfRow(r): the neighbours of centre row r.
template <typename HitsOfRow>
double reserveNonZeros(CsrMatrix& a, const detail::NonZeroCheck& beforeAllocating, HitsOfRow&& hitsOfRow) {
  const Index n = a.rows;
  const Index s = std::min(n, kSampleRows);
  std::int64_t hits = 0;
  for (Index i = 0; i < s; ++i) hits += hitsOfRow(static_cast<Index>((std::int64_t{i} * n) / s));
  const double perRow = static_cast<double>(hits) / static_cast<double>(s);
  const double estimate = 1.15 * perRow * static_cast<double>(n) + 4096.0;
  const auto reserve = static_cast<std::size_t>(std::min(estimate, static_cast<double>(kMaxNonZeros)));
  if (beforeAllocating) beforeAllocating(reserve);
  try {
    a.colIdx.reserve(reserve);
    a.values.reserve(reserve);
  } catch (const std::bad_alloc&) {
    // The estimate's margin may not fit where the matrix itself does: grow as needed instead.
  }
  return perRow;
}

}  // namespace

void detail::checkAssemblyArguments(const Points& centres, double sigma, double lambda) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) {
    throw InvalidArgument("assembleWendland: sigma must be positive and finite, got " +
                          std::to_string(sigma));
  }
  if (!(lambda >= 0.0) || !std::isfinite(lambda)) {
    throw InvalidArgument("assembleWendland: lambda must be non-negative and finite, got " +
                          std::to_string(lambda));
  }
  if (centres.rows() > std::numeric_limits<Index>::max()) {
    throw InvalidArgument("assembleWendland: too many centres (" + std::to_string(centres.rows()) +
                          ")");
  }
  checkCentres(centres);
}

namespace {

/// The assembly with the radius searches on a k-d tree of the centres (where the grid is not usable).
CsrMatrix assembleOnTree(const Points& centres, double sigma, double lambda, const NeighborIndex& index,
                         const detail::NonZeroCheck& beforeAllocating, Interrupter* interrupter, CsrMatrix* storage) {
  const auto n = static_cast<Index>(centres.rows());
  CsrMatrix a = noEntries(n, storage);
  if (n == 0) return a;

  reserveNonZeros(a, beforeAllocating, [&](Index r) {
    const NeighborLists lists = index.radiusSearch(centres.middleRows(r, 1), sigma);
    return lists.offsets.back();
  });
  const double diagonal = 1.0 + lambda;

  Points block;
  std::vector<std::int64_t> rowStart;
  for (Index start = 0; start < n; start += std::min(kChunkRows, n - start)) {
    const Index len = std::min(kChunkRows, n - start);
    block = centres.middleRows(start, len);
    // Each row is sorted by column below: the hits' distance order is not needed.
    const NeighborLists lists = index.radiusSearchUnsorted(block, sigma, interrupter);

    // Entries per row, as offsets into this chunk's part of the matrix.
    rowStart.assign(lists.offsets.begin(), lists.offsets.end());

    const std::int64_t base = a.rowPtr[static_cast<std::size_t>(start)];
    const std::int64_t total = base + rowStart.back();
    if (total > kMaxNonZeros) {
      throw InvalidArgument("assembleWendland: more than 2^31 - 1 non-zeros (sigma " +
                            std::to_string(sigma) + " is too large for " + std::to_string(n) +
                            " centres)");
    }
    for (Index i = 0; i < len; ++i) {
      a.rowPtr[static_cast<std::size_t>(start + i) + 1] =
          static_cast<Index>(base + rowStart[static_cast<std::size_t>(i) + 1]);
    }
    a.colIdx.resize(static_cast<std::size_t>(total));
    a.values.resize(static_cast<std::size_t>(total));

    // Each row: copy (column, distance) to a per-thread scratch, sort by column (the search sorts
    // by distance), then write φ(d/σ), with 1 + λ on the diagonal.
    std::exception_ptr error;
#pragma omp parallel
    {
      std::vector<Entry> scratch;
#pragma omp for schedule(dynamic, 256)
      for (Index i = 0; i < len; ++i) {
        try {
          const auto from = static_cast<std::size_t>(lists.offsets[static_cast<std::size_t>(i)]);
          const auto to = static_cast<std::size_t>(lists.offsets[static_cast<std::size_t>(i) + 1]);
          scratch.clear();
          for (std::size_t k = from; k < to; ++k) scratch.push_back(Entry{lists.indices[k], lists.distances[k]});
          sortByColumn(scratch.data(), scratch.data() + scratch.size(), [](const Entry& e) { return e.col; });
          const Index row = start + i;
          const auto out = static_cast<std::size_t>(base + rowStart[static_cast<std::size_t>(i)]);
          Index* col = a.colIdx.data() + out;
          double* val = a.values.data() + out;
          for (std::size_t k = 0; k < scratch.size(); ++k) {
            col[k] = scratch[k].col;
            val[k] = scratch[k].col == row ? diagonal : wendland(scratch[k].distance / sigma);
          }
        } catch (...) {
#pragma omp critical(duplexfit_wendland_error)
          if (!error) error = std::current_exception();
        }
      }
    }
    if (error) std::rethrow_exception(error);
  }
  return a;
}

/// The assembly with the radius searches on a grid of σ cells over the centres. In each chunk every thread
/// takes a contiguous run of rows, collects each row's entries (sorted by column, with squared distances)
/// in its own buffer and counts them; after the prefix sum of the counts it copies its buffer into place,
/// taking the square roots there, where the rows' independent roots overlap (in the search loop every hit
/// waited on its own): 27 → 19 ns a non-zero on a fandisk_550k-sized level.
CsrMatrix assembleOnGrid(const Points& centres, double sigma, double lambda, const detail::CellGrid& grid,
                         const detail::NonZeroCheck& beforeAllocating, Interrupter* interrupter, CsrMatrix* storage) {
  const auto n = static_cast<Index>(centres.rows());
  CsrMatrix a = noEntries(n, storage);
  if (n == 0) return a;
  detail::SearchStop stop(interrupter);
  const auto query = [&centres](Index i, double* q) {
    for (int c = 0; c < 3; ++c) q[c] = centres(i, c);
  };
  const double hitsPerRow = reserveNonZeros(a, beforeAllocating, [&](Index r) {
    double q[3];
    query(r, q);
    std::int64_t hits = 0;
    grid.within(q, sigma, [&hits](Index, double) { ++hits; });
    return hits;
  });
  const double diagonal = 1.0 + lambda;
  const auto threads = static_cast<std::size_t>(std::max(1, detail::maxThreads()));
  // Each thread's entries of its rows; `used` of them are set (the vector only grows, by resize, so a hit
  // is two plain stores, not a push_back of a temporary). Sized once from the sampled rows' hits, with the
  // collection's scratch (about six candidates a hit), and not zero-filled: growing it by doubling from
  // empty at every level copied and cleared each page several times (2% of wheel_29k's CPU time).
  struct Buffer {
    detail::ScratchVector<detail::CellGrid::Hit> entries;
    std::size_t used = 0;
  };
  std::vector<Buffer> buffers(threads);
  {
    const double rowsPerThread = static_cast<double>(std::min(kChunkRows, n)) / static_cast<double>(threads) + 1.0;
    const auto expected = static_cast<std::size_t>(std::min(1.15 * hitsPerRow * rowsPerThread + 8.0 * hitsPerRow + 4096.0,
                                                            static_cast<double>(kMaxNonZeros)));
    try {
      for (Buffer& b : buffers) b.entries.resize(expected);
    } catch (const std::bad_alloc&) {
      // Grown as needed instead.
    }
  }
  std::vector<std::int64_t> rowStart;
  for (Index start = 0; start < n; start += std::min(kChunkRows, n - start)) {
    if (stop.skip(0)) break;
    const Index len = std::min(kChunkRows, n - start);
    rowStart.assign(static_cast<std::size_t>(len) + 1, 0);
    std::exception_ptr error;
    std::atomic<bool> failed{false};
    const auto fail = [&] {
#pragma omp critical(duplexfit_wendland_error)
      if (!error) error = std::current_exception();
      failed.store(true);
    };
#pragma omp parallel num_threads(static_cast<int>(threads))
    {
      const auto t = static_cast<std::size_t>(detail::threadId()), nt = static_cast<std::size_t>(detail::teamSize());
      const auto first = static_cast<Index>(static_cast<std::int64_t>(len) * static_cast<std::int64_t>(t) / static_cast<std::int64_t>(nt));
      const auto last = static_cast<Index>(static_cast<std::int64_t>(len) * static_cast<std::int64_t>(t + 1) / static_cast<std::int64_t>(nt));
      Buffer& buffer = buffers[t];
      try {
        buffer.used = 0;
        for (Index i = first; i < last; ++i) {
          const std::size_t before = buffer.used;
          double q[3];
          query(start + i, q);
          buffer.used += grid.collect(q, sigma, buffer.entries, before);
          sortByColumn(buffer.entries.data() + before, buffer.entries.data() + buffer.used,
                       [](const detail::CellGrid::Hit& h) { return h.id; });
          rowStart[static_cast<std::size_t>(i) + 1] = static_cast<std::int64_t>(buffer.used - before);
        }
      } catch (...) {
        fail();
      }
#pragma omp barrier
#pragma omp single
      {
        try {
          if (!failed.load()) {
            for (std::size_t i = 0; i < static_cast<std::size_t>(len); ++i) rowStart[i + 1] += rowStart[i];
            const std::int64_t base = a.rowPtr[static_cast<std::size_t>(start)];
            const std::int64_t total = base + rowStart.back();
            if (total > kMaxNonZeros) {
              throw InvalidArgument("assembleWendland: more than 2^31 - 1 non-zeros (sigma " + std::to_string(sigma) +
                                    " is too large for " + std::to_string(n) + " centres)");
            }
            for (Index i = 0; i < len; ++i) {
              a.rowPtr[static_cast<std::size_t>(start + i) + 1] = static_cast<Index>(base + rowStart[static_cast<std::size_t>(i) + 1]);
            }
            a.colIdx.resize(static_cast<std::size_t>(total));
            a.values.resize(static_cast<std::size_t>(total));
          }
        } catch (...) {
          fail();
        }
      }
      if (!failed.load()) {
        const auto out = static_cast<std::size_t>(a.rowPtr[static_cast<std::size_t>(start + first)]);
        Index* col = a.colIdx.data() + out;
        double* val = a.values.data() + out;
        const detail::CellGrid::Hit* entries = buffer.entries.data();
        std::size_t k = 0;
        for (Index i = first; i < last; ++i) {
          const Index row = start + i;
          const auto end = static_cast<std::size_t>(rowStart[static_cast<std::size_t>(i) + 1] - rowStart[static_cast<std::size_t>(first)]);
          // The same distance as within()'s (the square root of the same squared distance), so the same φ.
          for (; k < end; ++k) {
            col[k] = entries[k].id;
            val[k] = entries[k].id == row ? diagonal : wendland(std::sqrt(entries[k].squared) / sigma);
          }
        }
      }
    }
    if (error) std::rethrow_exception(error);
  }
  stop.throwIfStopped();
  return a;
}

/// The assembly on the grid when its table fits `maxGridCells`, else on a k-d tree.
CsrMatrix assembleAny(const Points& centres, double sigma, double lambda, const detail::NonZeroCheck& beforeAllocating,
                      Interrupter* interrupter, std::size_t maxGridCells, CsrMatrix* storage) {
  detail::checkAssemblyArguments(centres, sigma, lambda);
  const detail::CellGrid grid(centres, sigma, maxGridCells);
  if (grid.usable()) return assembleOnGrid(centres, sigma, lambda, grid, beforeAllocating, interrupter, storage);
  const NeighborIndex index(centres);
  return assembleOnTree(centres, sigma, lambda, index, beforeAllocating, interrupter, storage);
}

}  // namespace

CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda) {
  return assembleAny(centres, sigma, lambda, {}, nullptr, detail::CellGrid::kDefaultMaxCells, nullptr);
}

namespace detail {

CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NonZeroCheck& beforeAllocating,
                           Interrupter* interrupter, std::size_t maxGridCells, CsrMatrix* storage) {
  return assembleAny(centres, sigma, lambda, beforeAllocating, interrupter, maxGridCells, storage);
}

}  // namespace detail

}  // namespace duplexfit
