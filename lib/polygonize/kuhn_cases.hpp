// The marching-tetrahedra case table of one grid cell split into 6 Kuhn (Freudenthal) tetrahedra
// around its main diagonal, derived at first use from the geometry of the unit cube (no copied
// tables): for every sign pattern of the 8 corners, the oriented contour polygons as cell edges.
#pragma once

#include <cstdint>

namespace duplexfit::detail {

/// Corners of a cell are bitmasks: bit 0 = +x, bit 1 = +y, bit 2 = +z.
/// An edge of the Kuhn triangulation runs from corner `from` to corner `to` with from ⊂ to (as bit
/// sets), so its direction to − from = to ^ from is a non-empty subset of {x, y, z}: 3 axis edges,
/// 3 face diagonals and the main diagonal, all pointing toward +x/+y/+z.
struct KuhnEdge {
  std::uint8_t from = 0;
  std::uint8_t to = 0;
};

/// Number of distinct edges used by the 6 tetrahedra of one cell (12 cube edges, 6 face diagonals,
/// 1 main diagonal).
constexpr int kKuhnEdgeCount = 19;

/// One contour polygon inside one tetrahedron: 3 or 4 cell-edge indices in cyclic order, oriented
/// so that the normal (right-hand rule) points from the inside corners (f ≥ iso) to the outside
/// ones.
struct KuhnPolygon {
  std::uint8_t size = 0;
  std::uint8_t edges[4] = {0, 0, 0, 0};
};

/// The polygons of one sign pattern (at most one per tetrahedron), in tetrahedron order.
struct KuhnCase {
  std::uint8_t count = 0;
  KuhnPolygon polygons[6];
};

/// edges[e] for e < kKuhnEdgeCount, and cases[mask] where bit c of mask says corner c is inside.
struct KuhnTable {
  KuhnEdge edges[kKuhnEdgeCount];
  KuhnCase cases[256];
};

/// The table, built once (thread-safe static initialisation).
const KuhnTable& kuhnTable();

}  // namespace duplexfit::detail
