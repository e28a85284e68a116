// Assembly of the level system over a neighbour index the caller already has (private to the library):
// the fit's merge search and its CSR pattern then share one k-d tree per level (docs/method.md §3.5, §5).
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include "duplexfit/neighbors.hpp"
#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::detail {

/// assembleWendland(centres, sigma, lambda) with the radius searches run on `superset`, an index of a
/// point set that contains every centre: rowOf[i] is the centre row of indexed point i (whose
/// coordinates must equal that row's), or −1 when point i is not a centre. The matrix is identical to
/// the one assembled over an index of the centres alone.
/// @throws InvalidArgument as assembleWendland, or when rowOf.size() ≠ superset.size().
/// `beforeAllocating` (when set) is called with the sampled estimate of the non-zeros before the CSR
/// arrays are reserved: the fit's memory check (ResourceLimits), which may throw. The radius searches
/// poll `interrupter` (may be null; @throws Cancelled).
using NonZeroCheck = std::function<void(std::size_t estimatedNonZeros)>;
CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NeighborIndex& superset,
                           const std::vector<Index>& rowOf, const NonZeroCheck& beforeAllocating = {},
                           Interrupter* interrupter = nullptr);
/// assembleWendland(centres, sigma, lambda) over an index of the centres, with the check and poll above.
CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda, const NonZeroCheck& beforeAllocating,
                           Interrupter* interrupter = nullptr);

}  // namespace duplexfit::detail
