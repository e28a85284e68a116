// The tree behind TriangleBvh (private to the library): nodes in depth-first order with the left child
// next to its parent, triangles reordered into leaf order with their corners stored contiguously.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "core/default_init.hpp"
#include "duplexfit/measure.hpp"

namespace duplexfit {

struct TriangleBvh::Data {
  struct Node {
    double lo[3], hi[3];
    // A "coin" around the node's triangles: the cylinder with centre c, unit axis n (the area-weighted
    // mean normal), radius rho and half-height halfHeight. Near the leaves the triangles are nearly
    // planar and the coin bounds the distance far more tightly than the box.
    double c[3], n[3], rho, halfHeight;
    std::uint32_t index;  ///< leaf: first triangle (leaf order); inner: right child (left = this + 1)
    std::uint32_t count;  ///< triangles in a leaf; 0 for an inner node
  };
  // Sized once and written by the build (in parallel): not zero-filled first (fandisk_550k's zero mesh:
  // 0.4 GB of tables, a serial clearing pass before).
  detail::ScratchVector<Node> nodes;
  detail::ScratchVector<double> corners;       ///< 9 per triangle in leaf order: a, b, c
  detail::ScratchVector<double> normals;       ///< 3 per triangle in leaf order: unit normal (zero if degenerate)
  detail::ScratchVector<std::int64_t> faceOf;  ///< leaf order → face index
  int depth = 0;

  const double* triangle(std::size_t k) const { return corners.data() + 9 * k; }
  const double* normal(std::size_t k) const { return normals.data() + 3 * k; }

  /// Squared distance from q to a node's box (0 inside).
  static double boxDistance2(const Node& n, const double q[3]) {
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double below = n.lo[k] - q[k];
      const double above = q[k] - n.hi[k];
      const double d = below > 0.0 ? below : (above > 0.0 ? above : 0.0);
      d2 += d * d;
    }
    return d2;
  }

  /// Squared distance from q to a node's coin (a lower bound of the distance to its triangles).
  static double coinDistance2(const Node& n, const double q[3]) {
    const double w[3] = {q[0] - n.c[0], q[1] - n.c[1], q[2] - n.c[2]};
    const double h = w[0] * n.n[0] + w[1] * n.n[1] + w[2] * n.n[2];
    const double r2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2] - h * h;
    const double axial = std::abs(h) - n.halfHeight;
    const double radial = (r2 > 0.0 ? std::sqrt(r2) : 0.0) - n.rho;
    return (axial > 0.0 ? axial * axial : 0.0) + (radial > 0.0 ? radial * radial : 0.0);
  }

  /// The larger of the two lower bounds (the coin is skipped when the box alone reaches `cutoff`).
  static double lowerBound2(const Node& n, const double q[3], double cutoff) {
    const double box = boxDistance2(n, q);
    if (box >= cutoff) return box;
    const double coin = coinDistance2(n, q);
    return box > coin ? box : coin;
  }
};

}  // namespace duplexfit
