// Checks of one slice layer: every loop closed (≥ 3 distinct vertices, no repeated closing point), simple,
// disjoint from the other loops, oriented by depth (counter-clockwise outer at even depth, clockwise holes
// at odd depth) and inside its parent; the layer's area is the sum of the signed loop areas.
#pragma once

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include "duplexfit/slice.hpp"

namespace duplexfit::slicetest {

inline double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

/// Whether segments ab and cd share a point (touching counts).
inline bool segmentsMeet(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                         const Eigen::Vector2d& d) {
  const double d1 = cross(c, d, a), d2 = cross(c, d, b), d3 = cross(a, b, c), d4 = cross(a, b, d);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  auto onSegment = [](const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r) {
    return std::min(p.x(), q.x()) <= r.x() && r.x() <= std::max(p.x(), q.x()) && std::min(p.y(), q.y()) <= r.y() &&
           r.y() <= std::max(p.y(), q.y());
  };
  return (d1 == 0 && onSegment(c, d, a)) || (d2 == 0 && onSegment(c, d, b)) || (d3 == 0 && onSegment(a, b, c)) ||
         (d4 == 0 && onSegment(a, b, d));
}

inline bool insidePolygon(const Points2& p, const Eigen::Vector2d& x) {
  bool in = false;
  for (Eigen::Index i = 0, j = p.rows() - 1; i < p.rows(); j = i++) {
    if ((p(i, 1) > x.y()) != (p(j, 1) > x.y()) &&
        x.x() < p(j, 0) + (x.y() - p(j, 1)) * (p(i, 0) - p(j, 0)) / (p(i, 1) - p(j, 1))) {
      in = !in;
    }
  }
  return in;
}

inline Eigen::Vector2d pt(const Points2& p, Eigen::Index i) { return p.row(i % p.rows()).transpose(); }

/// Counts self-intersections of a closed polyline (non-adjacent edges that meet).
inline int selfIntersections(const Points2& p) {
  const Eigen::Index n = p.rows();
  int hits = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // adjacent through the closing edge
      if (segmentsMeet(pt(p, i), pt(p, i + 1), pt(p, j), pt(p, j + 1))) ++hits;
    }
  }
  return hits;
}

/// Counts crossings between two closed polylines.
inline int crossings(const Points2& p, const Points2& q) {
  int hits = 0;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const Eigen::Vector2d a = pt(p, i), b = pt(p, i + 1);
    for (Eigen::Index j = 0; j < q.rows(); ++j) {
      if (segmentsMeet(a, b, pt(q, j), pt(q, j + 1))) ++hits;
    }
  }
  return hits;
}

inline void checkLayer(const SliceLayer& l) {
  double sum = 0.0;
  for (std::size_t i = 0; i < l.loops.size(); ++i) {
    CAPTURE(i);
    const SliceLoop& loop = l.loops[i];
    const Points2& p = loop.points;
    REQUIRE(p.rows() >= 3);
    for (Eigen::Index k = 0; k < p.rows(); ++k) CHECK((pt(p, k) - pt(p, k + 1)).norm() > 0.0);
    double a = 0.0;
    for (Eigen::Index k = 0; k < p.rows(); ++k) a += cross(Eigen::Vector2d::Zero(), pt(p, k), pt(p, k + 1));
    CHECK(0.5 * a == doctest::Approx(loop.area).epsilon(1e-9));
    sum += loop.area;
    CHECK(selfIntersections(p) == 0);
    CHECK(loop.outer() == (loop.depth % 2 == 0));
    if (loop.parent < 0) {
      CHECK(loop.depth == 0);
    } else {
      REQUIRE(loop.parent < static_cast<int>(i));  // depth-first order: the parent comes first
      const SliceLoop& parent = l.loops[static_cast<std::size_t>(loop.parent)];
      CHECK(parent.depth == loop.depth - 1);
      CHECK(insidePolygon(parent.points, pt(p, 0)));
      CHECK(std::abs(parent.area) > std::abs(loop.area));
    }
    // No crossings with later loops.
    for (std::size_t j = i + 1; j < l.loops.size(); ++j) CHECK(crossings(p, l.loops[j].points) == 0);
    // The number of loops containing it equals its depth.
    int containing = 0;
    for (std::size_t j = 0; j < l.loops.size(); ++j) {
      if (j != i && insidePolygon(l.loops[j].points, pt(p, 0))) ++containing;
    }
    CHECK(containing == loop.depth);
  }
  CHECK(l.area == doctest::Approx(sum).epsilon(1e-12));
}

}  // namespace duplexfit::slicetest
