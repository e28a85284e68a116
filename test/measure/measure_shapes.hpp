// Generated meshes of the measure tests: icospheres, tori, random triangle soups, single triangles.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include "duplexfit/measure.hpp"
#include "duplexfit/mesh.hpp"

namespace duplexfit::testing {

/// Reverses every face (inside out) when the mesh encloses a negative volume, so it is outward.
inline Mesh outward(Mesh m) {
  if (signedVolume(m) < 0.0) m.faces.col(1).swap(m.faces.col(2));
  return m;
}

/// An icosahedron subdivided `levels` times (20·4^levels faces), vertices on the sphere of radius r
/// around `centre`, outward-oriented.
inline Mesh icosphere(int levels, double r, const Eigen::RowVector3d& centre = Eigen::RowVector3d::Zero()) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Eigen::RowVector3d> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                       {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                       {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                       {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                       {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      const auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      const int id = static_cast<int>(v.size()) - 1;
      mid[key] = id;
      return id;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& tri : f) {
      const int a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      next.push_back({tri[0], a, c});
      next.push_back({tri[1], b, a});
      next.push_back({tri[2], c, b});
      next.push_back({a, b, c});
    }
    f = std::move(next);
  }
  Mesh m;
  m.vertices.resize(static_cast<Eigen::Index>(v.size()), 3);
  for (std::size_t i = 0; i < v.size(); ++i) m.vertices.row(static_cast<Eigen::Index>(i)) = centre + r * v[i];
  m.faces.resize(static_cast<Eigen::Index>(f.size()), 3);
  for (std::size_t i = 0; i < f.size(); ++i) {
    for (int k = 0; k < 3; ++k) m.faces(static_cast<Eigen::Index>(i), k) = f[i][static_cast<std::size_t>(k)];
  }
  return outward(m);
}

/// A torus (axis z, major radius R, minor radius r) as an n × m grid of quads split in two.
inline Mesh torus(int n, int m, double R, double r) {
  Mesh t;
  t.vertices.resize(n * m, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const double u = 2 * M_PI * i / n, w = 2 * M_PI * j / m;
      t.vertices.row(i * m + j) << (R + r * std::cos(w)) * std::cos(u), (R + r * std::cos(w)) * std::sin(u),
          r * std::sin(w);
    }
  }
  t.faces.resize(2 * n * m, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < m; ++j) {
      const int a = i * m + j, b = ((i + 1) % n) * m + j, c = ((i + 1) % n) * m + (j + 1) % m, d = i * m + (j + 1) % m;
      t.faces.row(2 * (i * m + j)) << a, b, c;
      t.faces.row(2 * (i * m + j) + 1) << a, c, d;
    }
  }
  return outward(t);
}

/// A mesh of the given triangles (9 numbers each), vertices not shared.
inline Mesh soup(std::initializer_list<std::array<double, 9>> tris) {
  Mesh m;
  m.vertices.resize(3 * static_cast<Eigen::Index>(tris.size()), 3);
  m.faces.resize(static_cast<Eigen::Index>(tris.size()), 3);
  Eigen::Index i = 0;
  for (const auto& t : tris) {
    for (int k = 0; k < 3; ++k) m.vertices.row(3 * i + k) << t[3 * k], t[3 * k + 1], t[3 * k + 2];
    m.faces.row(i) << static_cast<std::int32_t>(3 * i), static_cast<std::int32_t>(3 * i + 1),
        static_cast<std::int32_t>(3 * i + 2);
    ++i;
  }
  return m;
}

/// The largest distance between the sphere of radius r (centre c) and the mesh (chordal error):
/// r − min over faces of the distance from the centre to the face.
inline double chordalError(const Mesh& m, double r, const Eigen::Vector3d& c = Eigen::Vector3d::Zero()) {
  double inner = r;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    const ClosestPoint cp = closestPointOnTriangle(c, m.vertices.row(m.faces(f, 0)).transpose(),
                                                   m.vertices.row(m.faces(f, 1)).transpose(),
                                                   m.vertices.row(m.faces(f, 2)).transpose());
    inner = std::min(inner, cp.distance);
  }
  return r - inner;
}

}  // namespace duplexfit::testing
