// Small hand-made meshes for the topology and mesh I/O tests: an octahedron, a cube and a
// tetrahedron, all outward-oriented (counter-clockwise seen from outside).
#pragma once

#include "duplexfit/mesh.hpp"

namespace duplexfit::testing {

/// The octahedron with vertices ±r on the axes (V = 6, F = 8, volume 4r³/3).
inline Mesh octahedron(double r = 1.0) {
  Mesh m;
  m.vertices.resize(6, 3);
  m.vertices << r, 0, 0, -r, 0, 0, 0, r, 0, 0, -r, 0, 0, 0, r, 0, 0, -r;
  m.faces.resize(8, 3);
  m.faces << 0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5;
  return m;
}

/// The cube [0, 1]³ as 12 triangles, two per side; side k uses faces 2k and 2k + 1.
inline Mesh cube() {
  Mesh m;
  m.vertices.resize(8, 3);
  m.vertices << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1;
  m.faces.resize(12, 3);
  m.faces << 0, 2, 1, 0, 3, 2,  // z = 0
      4, 5, 6, 4, 6, 7,         // z = 1
      0, 1, 5, 0, 5, 4,         // y = 0
      2, 3, 7, 2, 7, 6,         // y = 1
      0, 4, 7, 0, 7, 3,         // x = 0
      1, 2, 6, 1, 6, 5;         // x = 1
  return m;
}

/// A tetrahedron with one corner at `origin` and edges of length `size` along the axes.
inline Mesh tetrahedron(const Eigen::RowVector3d& origin, double size = 1.0) {
  Mesh m;
  m.vertices.resize(4, 3);
  m.vertices.row(0) = origin;
  m.vertices.row(1) = origin + Eigen::RowVector3d(size, 0, 0);
  m.vertices.row(2) = origin + Eigen::RowVector3d(0, size, 0);
  m.vertices.row(3) = origin + Eigen::RowVector3d(0, 0, size);
  m.faces.resize(4, 3);
  m.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return m;
}

/// The union of two meshes (b's indices shifted).
inline Mesh concatenate(const Mesh& a, const Mesh& b) {
  Mesh m;
  m.vertices.resize(a.vertices.rows() + b.vertices.rows(), 3);
  m.vertices << a.vertices, b.vertices;
  m.faces.resize(a.faces.rows() + b.faces.rows(), 3);
  m.faces << a.faces, (b.faces.array() + static_cast<std::int32_t>(a.vertices.rows())).matrix();
  return m;
}

}  // namespace duplexfit::testing
