// Independent mesh checks for the polygonize tests: topology (boundary, non-manifold and
// inconsistently oriented edges, non-manifold vertices, components, Euler characteristic), area and
// signed volume. Kept separate from lib/core/mesh.cpp on purpose, so the two implementations check
// each other.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <numeric>
#include <tuple>
#include <vector>

#include "duplexfit/mesh.hpp"

namespace duplexfit::testing::polygonize {

struct Topology {
  std::int64_t vertices = 0, edges = 0, faces = 0;
  std::int64_t boundaryEdges = 0, nonManifoldEdges = 0, inconsistentEdges = 0;
  std::int64_t nonManifoldVertices = 0, degenerateFaces = 0, unreferencedVertices = 0;
  std::int64_t components = 0;
  std::int64_t euler = 0;
  bool closedManifold() const {
    return boundaryEdges == 0 && nonManifoldEdges == 0 && inconsistentEdges == 0 &&
           nonManifoldVertices == 0 && degenerateFaces == 0 && unreferencedVertices == 0;
  }
};

class UnionFind {
 public:
  explicit UnionFind(std::size_t n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }
  std::size_t find(std::size_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }
  void unite(std::size_t a, std::size_t b) { parent_[find(a)] = find(b); }

 private:
  std::vector<std::size_t> parent_;
};

inline Topology topology(const Mesh& mesh) {
  Topology t;
  const std::size_t nv = static_cast<std::size_t>(mesh.vertices.rows());
  const std::size_t nf = static_cast<std::size_t>(mesh.faces.rows());
  t.faces = static_cast<std::int64_t>(nf);
  // Half-edges as (min, max, face, forward?).
  std::vector<std::tuple<std::int32_t, std::int32_t, std::size_t, bool>> half;
  half.reserve(3 * nf);
  std::vector<char> used(nv, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    const Eigen::Index fi = static_cast<Eigen::Index>(f);
    const std::int32_t v[3] = {mesh.faces(fi, 0), mesh.faces(fi, 1), mesh.faces(fi, 2)};
    if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2]) ++t.degenerateFaces;
    for (int c = 0; c < 3; ++c) {
      used[static_cast<std::size_t>(v[c])] = 1;
      const std::int32_t a = v[c], b = v[(c + 1) % 3];
      half.emplace_back(std::min(a, b), std::max(a, b), f, a < b);
    }
  }
  std::sort(half.begin(), half.end());
  UnionFind faces(nf);
  const auto sameEdge = [](const auto& a, const auto& b) {
    return std::get<0>(a) == std::get<0>(b) && std::get<1>(a) == std::get<1>(b);
  };
  for (auto first = half.begin(); first != half.end();) {
    auto last = first + 1;
    while (last != half.end() && sameEdge(*last, *first)) {
      faces.unite(std::get<2>(*first), std::get<2>(*last));
      ++last;
    }
    ++t.edges;
    const auto n = last - first;
    if (n == 1) ++t.boundaryEdges;
    if (n > 2) ++t.nonManifoldEdges;
    if (n == 2 && std::get<3>(*first) == std::get<3>(*(first + 1))) ++t.inconsistentEdges;
    first = last;
  }
  // Vertex fans: the faces around a vertex, linked when they share an edge at the vertex.
  std::vector<std::size_t> start(nv + 1, 0);
  for (std::size_t f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) {
      ++start[static_cast<std::size_t>(mesh.faces(static_cast<Eigen::Index>(f), c)) + 1];
    }
  }
  for (std::size_t v = 0; v < nv; ++v) start[v + 1] += start[v];
  std::vector<std::size_t> incident(start[nv]);
  std::vector<std::size_t> fill(start.begin(), start.end() - 1);
  for (std::size_t f = 0; f < nf; ++f) {
    for (int c = 0; c < 3; ++c) {
      incident[fill[static_cast<std::size_t>(mesh.faces(static_cast<Eigen::Index>(f), c))]++] = f;
    }
  }
  for (std::size_t v = 0; v < nv; ++v) {
    const std::size_t n = start[v + 1] - start[v];
    if (n == 0) continue;
    UnionFind fan(n);
    std::vector<std::pair<std::int32_t, std::size_t>> others;  // (other vertex, local face)
    for (std::size_t l = 0; l < n; ++l) {
      const Eigen::Index f = static_cast<Eigen::Index>(incident[start[v] + l]);
      for (int c = 0; c < 3; ++c) {
        if (mesh.faces(f, c) != static_cast<std::int32_t>(v)) {
          others.emplace_back(mesh.faces(f, c), l);
        }
      }
    }
    std::sort(others.begin(), others.end());
    for (std::size_t i = 1; i < others.size(); ++i) {
      if (others[i].first == others[i - 1].first) fan.unite(others[i].second, others[i - 1].second);
    }
    std::size_t roots = 0;
    for (std::size_t l = 0; l < n; ++l) roots += fan.find(l) == l;
    if (roots > 1) ++t.nonManifoldVertices;
  }
  for (std::size_t v = 0; v < nv; ++v) {
    if (used[v]) {
      ++t.vertices;
    } else {
      ++t.unreferencedVertices;
    }
  }
  for (std::size_t f = 0; f < nf; ++f) t.components += faces.find(f) == f;
  t.euler = t.vertices - t.edges + t.faces;
  return t;
}

inline double area(const Mesh& mesh) {
  double a = 0.0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const Eigen::Vector3d p0 = mesh.vertices.row(mesh.faces(f, 0)).transpose();
    const Eigen::Vector3d p1 = mesh.vertices.row(mesh.faces(f, 1)).transpose();
    const Eigen::Vector3d p2 = mesh.vertices.row(mesh.faces(f, 2)).transpose();
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

inline double volume(const Mesh& mesh) {
  double v = 0.0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    const Eigen::Vector3d p0 = mesh.vertices.row(mesh.faces(f, 0)).transpose();
    const Eigen::Vector3d p1 = mesh.vertices.row(mesh.faces(f, 1)).transpose();
    const Eigen::Vector3d p2 = mesh.vertices.row(mesh.faces(f, 2)).transpose();
    v += p0.dot(p1.cross(p2)) / 6.0;
  }
  return v;
}

inline bool identical(const Mesh& a, const Mesh& b) {
  return a.vertices.rows() == b.vertices.rows() && a.faces.rows() == b.faces.rows() &&
         a.vertices == b.vertices && a.faces == b.faces;
}

/// The triangles of m as corner positions (each rotated to start at its smallest corner, keeping the
/// orientation), sorted: equal for meshes with the same triangles in any vertex and face order.
inline std::vector<std::array<std::array<double, 3>, 3>> sortedTriangles(const Mesh& m) {
  std::vector<std::array<std::array<double, 3>, 3>> out;
  for (Eigen::Index i = 0; i < m.faces.rows(); ++i) {
    std::array<std::array<double, 3>, 3> t{};
    for (int c = 0; c < 3; ++c) {
      for (int d = 0; d < 3; ++d) t[static_cast<std::size_t>(c)][static_cast<std::size_t>(d)] = m.vertices(m.faces(i, c), d);
    }
    std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    out.push_back(t);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace duplexfit::testing::polygonize
