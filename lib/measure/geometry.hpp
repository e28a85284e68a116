// Small geometric kernels of the measure module on raw double triples (private to the library).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "duplexfit/measure.hpp"

namespace duplexfit::geom {

inline void sub(const double* a, const double* b, double* out) {
  out[0] = a[0] - b[0];
  out[1] = a[1] - b[1];
  out[2] = a[2] - b[2];
}
inline double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline void cross(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}
inline double norm2(const double* a) { return dot(a, a); }
inline double dist2(const double* a, const double* b) {
  double d[3];
  sub(a, b, d);
  return norm2(d);
}

/// Closest point of triangle tri = (a, b, c) (9 doubles) to q; returns the squared distance and writes
/// the point, feature and local index. Degenerate triangles fall back to their three edges.
double closestOnTriangle(const double* q, const double* tri, double* point, TriangleFeature& feature,
                         int& local);

/// Whether any two of the first `n` triangles, or one of them and one of the other `m`, touch or cross
/// beyond the corners they share, decided as the self-intersection test decides a pair: corners with
/// equal ids are the same vertex, the tolerance is 1e-10 of the longer longest edge, and a degenerate
/// triangle (a repeated id, or no area) meets nothing. Corners: 9 doubles a triangle, ids: 3 a triangle,
/// the n first, then the m others. Each triangle is prepared once; pairs whose boxes are apart are not
/// tested.
bool anyTrianglesMeet(const double* corners, const std::int32_t* ids, std::size_t n, std::size_t m);

/// Whether a triangle is degenerate for the closest-point test: |ab × ac|² ≤ 1e-24 · |ab|² · |ac|²
/// (or an edge of zero length).
inline bool nearlyDegenerate(const double* ab, const double* ac) {
  double n[3];
  cross(ab, ac, n);
  const double l = norm2(ab) * norm2(ac);
  return !(norm2(n) > 1e-24 * l) || l == 0.0;
}

}  // namespace duplexfit::geom
