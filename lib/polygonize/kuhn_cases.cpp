// Derives the Kuhn marching-tetrahedra case table from cube geometry. Orientation is decided on the
// midpoint surface (every crossing at its edge midpoint), which is the 0-level set of the piecewise
// linear interpolant of ±1 corner signs; the polygon order does not depend on where the crossings
// actually sit, so the table is exact for any field.
#include "kuhn_cases.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

namespace duplexfit::detail {

namespace {

using Vec = std::array<int, 3>;

/// Twice the corner position, so that edge midpoints have integer coordinates.
Vec corner2(int c) { return {2 * (c & 1), 2 * ((c >> 1) & 1), 2 * ((c >> 2) & 1)}; }

Vec sub(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec add(const Vec& a, const Vec& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
int dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

class Builder {
 public:
  Builder() {
    for (auto& row : index_) row.fill(-1);
    // The 6 tetrahedra: monotone paths 0 → e_a → e_a + e_b → (1,1,1) over the permutations (a, b,
    // c).
    const int perms[6][2] = {{0, 1}, {0, 2}, {1, 0}, {1, 2}, {2, 0}, {2, 1}};
    for (int t = 0; t < 6; ++t) {
      const int a = 1 << perms[t][0];
      const int b = 1 << perms[t][1];
      tets_[t] = {0, a, a | b, 7};
      for (int i = 0; i < 4; ++i) {
        for (int j = i + 1; j < 4; ++j) addEdge(tets_[t][i], tets_[t][j]);
      }
    }
    if (count_ != kKuhnEdgeCount) throw std::logic_error("Kuhn triangulation: wrong edge count");
  }

  KuhnTable build() {
    for (int mask = 0; mask < 256; ++mask) {
      KuhnCase& out = table_.cases[mask];
      for (const auto& tet : tets_) {
        std::array<int, 4> in{}, outside{};
        int nIn = 0, nOut = 0;
        for (int v : tet) {
          if ((mask >> v) & 1) {
            in[nIn++] = v;
          } else {
            outside[nOut++] = v;
          }
        }
        if (nIn == 0 || nOut == 0) continue;
        KuhnPolygon& poly = out.polygons[out.count++];
        if (nIn == 1 || nOut == 1) {
          // One corner alone on its side: a triangle on its three edges.
          const int apex = nIn == 1 ? in[0] : outside[0];
          const auto& others = nIn == 1 ? outside : in;
          poly.size = 3;
          for (int i = 0; i < 3; ++i) poly.edges[i] = edge(apex, others[i]);
          // The normal must point away from a lone inside corner, toward a lone outside corner.
          const Vec m0 = midpoint2(poly.edges[0]);
          const Vec n = cross(sub(midpoint2(poly.edges[1]), m0), sub(midpoint2(poly.edges[2]), m0));
          const Vec away = sub(m0, corner2(apex));
          const bool flip = nIn == 1 ? dot(n, away) < 0 : dot(n, away) > 0;
          if (flip) std::swap(poly.edges[1], poly.edges[2]);
        } else {
          // Two and two: a quadrilateral whose consecutive edges share a tetrahedron corner.
          poly.size = 4;
          poly.edges[0] = edge(in[0], outside[0]);
          poly.edges[1] = edge(in[0], outside[1]);
          poly.edges[2] = edge(in[1], outside[1]);
          poly.edges[3] = edge(in[1], outside[0]);
          const Vec n = cross(sub(midpoint2(poly.edges[2]), midpoint2(poly.edges[0])),
                              sub(midpoint2(poly.edges[3]), midpoint2(poly.edges[1])));
          const Vec toOut = sub(add(corner2(outside[0]), corner2(outside[1])),
                                add(corner2(in[0]), corner2(in[1])));
          if (dot(n, toOut) < 0) std::swap(poly.edges[1], poly.edges[3]);
        }
      }
    }
    return table_;
  }

 private:
  void addEdge(int u, int v) {
    if (index_[u][v] >= 0) return;
    const bool uFirst = (u & v) == u;  // u ⊂ v
    table_.edges[count_] = {static_cast<std::uint8_t>(uFirst ? u : v),
                            static_cast<std::uint8_t>(uFirst ? v : u)};
    index_[u][v] = index_[v][u] = count_++;
  }
  std::uint8_t edge(int u, int v) const { return static_cast<std::uint8_t>(index_[u][v]); }
  /// Twice the midpoint of edge e, i.e. the sum of its corners' positions.
  Vec midpoint2(int e) const {
    const Vec s = add(corner2(table_.edges[e].from), corner2(table_.edges[e].to));
    return {s[0] / 2, s[1] / 2, s[2] / 2};
  }

  KuhnTable table_{};
  std::array<std::array<int, 8>, 8> index_{};
  std::array<std::array<int, 4>, 6> tets_{};
  int count_ = 0;
};

}  // namespace

const KuhnTable& kuhnTable() {
  static const KuhnTable table = Builder().build();
  return table;
}

}  // namespace duplexfit::detail
