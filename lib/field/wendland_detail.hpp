// Assembly of the level system with the fit's memory check and interrupter (private to the library).
#pragma once

#include <cstddef>
#include <functional>

#include "duplexfit/interrupter.hpp"
#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"
#include "spatial/cell_grid.hpp"

namespace duplexfit::detail {

/// Called with the sampled estimate of the non-zeros before the CSR arrays are reserved: the fit's memory
/// check (ResourceLimits), which may throw.
using NonZeroCheck = std::function<void(std::size_t estimatedNonZeros)>;

/// assembleWendland(centres, sigma, lambda) with `beforeAllocating` (when set) called as above; the
/// searches poll `interrupter` (may be null; @throws Cancelled). The searches run on a grid of σ cells
/// when its table has at most `maxGridCells` cells, else on a k-d tree: the matrix is the same. With
/// `storage`, the matrix is built in its arrays (their capacity taken over, `storage` left empty): a fit
/// hands each level's matrix on to the next level's assembly, whose pages are then already there.
CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NonZeroCheck& beforeAllocating,
                           Interrupter* interrupter = nullptr,
                           std::size_t maxGridCells = CellGrid::kDefaultMaxCells, CsrMatrix* storage = nullptr);

}  // namespace duplexfit::detail
