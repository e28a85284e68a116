// A spatially coherent order for batches of point queries (private to the library): consecutive queries
// then walk the same part of a search tree, which makes hinted or cached searches cheap.
#pragma once

#include <cstdint>
#include <vector>

#include "duplexfit/types.hpp"

namespace duplexfit::detail {

/// The indices of the queries sorted by the Morton code of their cell in a 1024³ grid over the queries'
/// bounding box (LSD radix sort, three 10-bit digits). Empty (meaning the input order) below minQueries
/// queries or beyond 2^32 − 1 of them.
std::vector<std::uint32_t> processingOrder(const Points& queries, std::int64_t minQueries);

}  // namespace duplexfit::detail
