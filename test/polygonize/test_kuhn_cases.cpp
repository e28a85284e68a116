// The derived Kuhn marching-tetrahedra table: 19 monotone edges, every polygon edge straddles the
// iso value, polygons stay inside one tetrahedron, and the contour inside a cell is a consistently
// oriented surface whose open edges lie on the cube faces.
#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <utility>

#include "polygonize/kuhn_cases.hpp"

using duplexfit::detail::kKuhnEdgeCount;
using duplexfit::detail::kuhnTable;
using duplexfit::detail::KuhnTable;

namespace {

/// True when the segment between the crossings on edges a and b lies on a face of the cube: all 4
/// corners of the two edges share one coordinate value.
bool onCubeFace(const KuhnTable& t, int a, int b) {
  const int corners[4] = {t.edges[a].from, t.edges[a].to, t.edges[b].from, t.edges[b].to};
  for (int axis = 0; axis < 3; ++axis) {
    const int bit = 1 << axis;
    bool all0 = true, all1 = true;
    for (int c : corners) {
      all0 = all0 && (c & bit) == 0;
      all1 = all1 && (c & bit) != 0;
    }
    if (all0 || all1) return true;
  }
  return false;
}

}  // namespace

TEST_SUITE("polygonize") {
  TEST_CASE("kuhn cases: 19 distinct monotone edges") {
    const KuhnTable& t = kuhnTable();
    for (int e = 0; e < kKuhnEdgeCount; ++e) {
      CHECK((t.edges[e].from & t.edges[e].to) == t.edges[e].from);
      CHECK(t.edges[e].from != t.edges[e].to);
      for (int f = 0; f < e; ++f) {
        CHECK(!(t.edges[e].from == t.edges[f].from && t.edges[e].to == t.edges[f].to));
      }
    }
    // The main diagonal and one diagonal per face.
    int diagonals = 0;
    for (int e = 0; e < kKuhnEdgeCount; ++e) {
      const int d = t.edges[e].from ^ t.edges[e].to;
      diagonals += d != 1 && d != 2 && d != 4;
    }
    CHECK(diagonals == 7);
  }

  TEST_CASE("kuhn cases: polygons straddle the iso value and close up inside the cell") {
    const KuhnTable& t = kuhnTable();
    CHECK(t.cases[0].count == 0);
    CHECK(t.cases[255].count == 0);
    for (int mask = 0; mask < 256; ++mask) {
      CAPTURE(mask);
      std::map<std::pair<int, int>, int> directed;  // segment (edge a → edge b) → count
      for (int p = 0; p < t.cases[mask].count; ++p) {
        const auto& poly = t.cases[mask].polygons[p];
        REQUIRE((poly.size == 3 || poly.size == 4));
        for (int s = 0; s < poly.size; ++s) {
          const auto& e = t.edges[poly.edges[s]];
          CHECK(((mask >> e.from) & 1) != ((mask >> e.to) & 1));
          ++directed[{poly.edges[s], poly.edges[(s + 1) % poly.size]}];
        }
      }
      // Inner segments are shared by two tetrahedra, traversed once each way; segments on the cube
      // faces are used once (the neighbouring cell supplies the opposite direction).
      for (const auto& [seg, count] : directed) {
        CHECK(count == 1);
        const bool reverse = directed.count({seg.second, seg.first}) > 0;
        CHECK(reverse != onCubeFace(t, seg.first, seg.second));
      }
    }
  }

  TEST_CASE("kuhn cases: complementary sign patterns give reversed polygons") {
    const KuhnTable& t = kuhnTable();
    for (int mask = 1; mask < 255; ++mask) {
      const auto& a = t.cases[mask];
      const auto& b = t.cases[255 - mask];
      REQUIRE(a.count == b.count);
      for (int p = 0; p < a.count; ++p) {
        REQUIRE(a.polygons[p].size == b.polygons[p].size);
        const int n = a.polygons[p].size;
        // Same edge set, opposite cyclic orientation.
        std::map<std::pair<int, int>, int> seg;
        for (int s = 0; s < n; ++s) {
          ++seg[{a.polygons[p].edges[s], a.polygons[p].edges[(s + 1) % n]}];
        }
        for (int s = 0; s < n; ++s) {
          CHECK(seg.count({b.polygons[p].edges[(s + 1) % n], b.polygons[p].edges[s]}) == 1);
        }
      }
    }
  }
}
