// Assembly of the level system Φ + λI (docs/method.md §5) as a CSR matrix: a radius search with the
// support σ gives each row's neighbours, which are re-sorted by column and mapped through φ(d/σ).
// Rows are processed in chunks so that the neighbour lists never exist for all rows at once.
#include "duplexfit/wendland.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "field/wendland_detail.hpp"

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

/// Sorts a row's entries by column: an insertion sort for the usual tens of entries (fewer
/// mispredicted branches than std::sort), std::sort for long rows.
void sortByColumn(Entry* first, Entry* last) {
  if (last - first > 64) {
    std::sort(first, last, [](const Entry& x, const Entry& y) { return x.col < y.col; });
    return;
  }
  for (Entry* i = first + (first != last); i < last; ++i) {
    const Entry e = *i;
    Entry* j = i;
    for (; j > first && e.col < j[-1].col; --j) *j = j[-1];
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

/// Non-zeros expected for the whole matrix from a sample of evenly spaced rows, with a margin, so
/// the CSR arrays can be reserved once (unused capacity stays virtual memory, never touched).
std::size_t estimateNonZeros(const NeighborIndex& index, const Points& centres, double sigma) {
  const Index n = static_cast<Index>(centres.rows());
  const Index s = std::min(n, kSampleRows);
  Points sample(s, 3);
  for (Index i = 0; i < s; ++i) {
    sample.row(i) = centres.row(static_cast<Index>((std::int64_t{i} * n) / s));
  }
  const NeighborLists lists = index.radiusSearch(sample, sigma);
  const double mean = static_cast<double>(lists.offsets.back()) / static_cast<double>(s);
  const double estimate = 1.15 * mean * static_cast<double>(n) + 4096.0;
  return static_cast<std::size_t>(std::min(estimate, static_cast<double>(kMaxNonZeros)));
}

}  // namespace

namespace {

void checkAssemblyArguments(const Points& centres, double sigma, double lambda) {
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

/// The assembly over an index of `centres` (rowOf empty) or of a superset of them (rowOf maps each
/// indexed point to its centre row, −1 for points that are not centres).
CsrMatrix assemble(const Points& centres, double sigma, double lambda, const NeighborIndex& index,
                   const std::vector<Index>& rowOf, const detail::NonZeroCheck& beforeAllocating = {},
                   Interrupter* interrupter = nullptr) {
  const auto n = static_cast<Index>(centres.rows());
  CsrMatrix a;
  a.rows = n;
  a.cols = n;
  a.rowPtr.assign(static_cast<std::size_t>(n) + 1, 0);
  if (n == 0) return a;

  const std::size_t reserve = estimateNonZeros(index, centres, sigma);
  if (beforeAllocating) beforeAllocating(reserve);
  try {
    a.colIdx.reserve(reserve);
    a.values.reserve(reserve);
  } catch (const std::bad_alloc&) {
    // The estimate's margin may not fit where the matrix itself does: grow as needed instead.
  }
  const double diagonal = 1.0 + lambda;
  const bool mapped = !rowOf.empty();
  auto columnOf = [&](Index indexed) { return mapped ? rowOf[static_cast<std::size_t>(indexed)] : indexed; };

  Points block;
  std::vector<std::int64_t> rowStart;
  for (Index start = 0; start < n; start += std::min(kChunkRows, n - start)) {
    const Index len = std::min(kChunkRows, n - start);
    block = centres.middleRows(start, len);
    // Each row is sorted by column below: the hits' distance order is not needed.
    const NeighborLists lists = index.radiusSearchUnsorted(block, sigma, interrupter);

    // Entries per row (neighbours that are centres), as offsets into this chunk's part of the matrix.
    rowStart.assign(static_cast<std::size_t>(len) + 1, 0);
    if (mapped) {
#pragma omp parallel for schedule(static)
      for (Index i = 0; i < len; ++i) {
        std::int64_t count = 0;
        for (auto k = lists.offsets[static_cast<std::size_t>(i)]; k < lists.offsets[static_cast<std::size_t>(i) + 1]; ++k) {
          count += columnOf(lists.indices[static_cast<std::size_t>(k)]) >= 0 ? 1 : 0;
        }
        rowStart[static_cast<std::size_t>(i) + 1] = count;
      }
      for (std::size_t i = 0; i < static_cast<std::size_t>(len); ++i) rowStart[i + 1] += rowStart[i];
    } else {
      rowStart.assign(lists.offsets.begin(), lists.offsets.end());
    }

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
          for (std::size_t k = from; k < to; ++k) {
            const Index col = columnOf(lists.indices[k]);
            if (col >= 0) scratch.push_back(Entry{col, lists.distances[k]});
          }
          sortByColumn(scratch.data(), scratch.data() + scratch.size());
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

}  // namespace

CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda) {
  checkAssemblyArguments(centres, sigma, lambda);
  const NeighborIndex index(centres);
  return assemble(centres, sigma, lambda, index, {});
}

namespace detail {

CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NonZeroCheck& beforeAllocating,
                           Interrupter* interrupter) {
  checkAssemblyArguments(centres, sigma, lambda);
  const NeighborIndex index(centres);
  return assemble(centres, sigma, lambda, index, {}, beforeAllocating, interrupter);
}

CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NeighborIndex& superset,
                           const std::vector<Index>& rowOf, const NonZeroCheck& beforeAllocating,
                           Interrupter* interrupter) {
  checkAssemblyArguments(centres, sigma, lambda);
  if (rowOf.size() != superset.size()) {
    throw InvalidArgument("assembleWendland: the row map has " + std::to_string(rowOf.size()) +
                          " entries for an index of " + std::to_string(superset.size()) + " points");
  }
  return assemble(centres, sigma, lambda, superset, rowOf, beforeAllocating, interrupter);
}

}  // namespace detail

}  // namespace duplexfit
