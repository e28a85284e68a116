// The surfaces module's edge-collapse simplifier (private to the library): quadric-error collapses with
// cleanMesh's safety checks (link condition, no merged triangles, no flipped or float32-degenerate
// neighbour), so a closed 2-manifold stays one. simplifyMesh falls back to it when meshoptimizer's result
// changes the topology.
#pragma once

#include <cstddef>

#include "duplexfit/mesh.hpp"

namespace duplexfit::detail {

/// Collapses edges, cheapest first, until at most `target` faces remain (0: no budget) or the cheapest
/// collapse costs more than maxError (0: no bound; the cost is the square root of the summed squared
/// distances to the planes of the merged vertices' original faces). `collapses` receives the count.
Mesh collapseSimplify(const Mesh& mesh, std::size_t target, double maxError, std::size_t* collapses = nullptr);

}  // namespace duplexfit::detail
