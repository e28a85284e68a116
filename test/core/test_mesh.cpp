// Mesh topology statistics, signed volume and area on hand-made meshes: a closed octahedron, an
// open cube, a flipped face, disjoint and touching tetrahedra, a non-manifold edge, degenerate
// and out-of-range faces.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "core/mesh_shapes.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/mesh.hpp"

namespace {

using duplexfit::analyzeTopology;
using duplexfit::InvalidArgument;
using duplexfit::Mesh;
using duplexfit::MeshTopology;
using duplexfit::signedVolume;
using duplexfit::surfaceArea;
using duplexfit::testing::concatenate;
using duplexfit::testing::cube;
using duplexfit::testing::octahedron;
using duplexfit::testing::tetrahedron;

/// The mesh without the faces in [first, first + count).
Mesh withoutFaces(const Mesh& mesh, Eigen::Index first, Eigen::Index count) {
  Mesh m = mesh;
  m.faces.resize(mesh.faces.rows() - count, 3);
  m.faces.topRows(first) = mesh.faces.topRows(first);
  m.faces.bottomRows(mesh.faces.rows() - first - count) =
      mesh.faces.bottomRows(mesh.faces.rows() - first - count);
  return m;
}

}  // namespace

TEST_SUITE("io") {

TEST_CASE("mesh: a closed octahedron is a watertight oriented sphere") {
  const Mesh m = octahedron(1.0);
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.vertices == 6);
  CHECK(t.edges == 12);
  CHECK(t.faces == 8);
  CHECK(t.eulerCharacteristic == 2);
  CHECK(t.components == 1);
  CHECK(t.boundaryEdges == 0);
  CHECK(t.nonManifoldEdges == 0);
  CHECK(t.nonManifoldVertices == 0);
  CHECK(t.inconsistentEdges == 0);
  CHECK(t.degenerateFaces == 0);
  CHECK(t.watertight());
  CHECK(t.manifold());
  CHECK(t.oriented());
  CHECK(signedVolume(m) == doctest::Approx(4.0 / 3.0).epsilon(1e-14));
  CHECK(surfaceArea(m) == doctest::Approx(4.0 * std::sqrt(3.0)).epsilon(1e-14));
}

TEST_CASE("mesh: volume and area of a cube far from the origin") {
  Mesh m = cube();
  m.vertices = (m.vertices * 2.0).rowwise() + Eigen::RowVector3d(1e6, -2e6, 3e6);
  CHECK(signedVolume(m) == doctest::Approx(8.0).epsilon(1e-12));
  CHECK(surfaceArea(m) == doctest::Approx(24.0).epsilon(1e-9));
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.eulerCharacteristic == 2);
  CHECK(t.watertight());
  CHECK(t.oriented());
  m.faces.col(1).swap(m.faces.col(2));  // every face flipped: still consistent, volume negative
  CHECK(signedVolume(m) == doctest::Approx(-8.0).epsilon(1e-12));
  CHECK(analyzeTopology(m).oriented());
}

TEST_CASE("mesh: a cube with one side removed has four boundary edges") {
  const Mesh m = withoutFaces(cube(), 2, 2);  // the z = 1 side
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.faces == 10);
  CHECK(t.boundaryEdges == 4);
  CHECK(t.edges == 17);
  CHECK(t.vertices == 8);
  CHECK(t.eulerCharacteristic == 1);
  CHECK_FALSE(t.watertight());
  CHECK(t.manifold());
  CHECK(t.oriented());
  CHECK(t.components == 1);
}

TEST_CASE("mesh: a flipped face makes its three edges inconsistent") {
  Mesh m = octahedron();
  std::swap(m.faces(3, 1), m.faces(3, 2));
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.inconsistentEdges == 3);
  CHECK_FALSE(t.oriented());
  CHECK(t.watertight());
  CHECK(t.manifold());
  CHECK(t.eulerCharacteristic == 2);
}

TEST_CASE("mesh: two disjoint tetrahedra are two components") {
  const Mesh m = concatenate(tetrahedron({0, 0, 0}), tetrahedron({5, 0, 0}));
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.components == 2);
  CHECK(t.vertices == 8);
  CHECK(t.edges == 12);
  CHECK(t.eulerCharacteristic == 4);
  CHECK(t.watertight());
  CHECK(t.manifold());
  CHECK(signedVolume(m) == doctest::Approx(2.0 / 6.0).epsilon(1e-14));
}

TEST_CASE("mesh: three faces on one edge make a non-manifold edge") {
  Mesh m;
  m.vertices.resize(5, 3);
  m.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
  m.faces.resize(3, 3);
  m.faces << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.nonManifoldEdges == 1);
  CHECK(t.boundaryEdges == 6);
  CHECK(t.edges == 7);
  CHECK(t.components == 1);
  CHECK_FALSE(t.manifold());
  CHECK_FALSE(t.watertight());
  CHECK(t.nonManifoldVertices == 0);
}

TEST_CASE("mesh: tetrahedra touching at one vertex make a non-manifold vertex") {
  Mesh m = concatenate(tetrahedron({0, 0, 0}), tetrahedron({-1, 0, 0}));
  // The second tetrahedron's corner 1 (vertex 5) lies at the origin: weld it to vertex 0.
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (m.faces(f, k) == 5) m.faces(f, k) = 0;
    }
  }
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.nonManifoldVertices == 1);
  CHECK(t.nonManifoldEdges == 0);
  CHECK(t.components == 2);
  CHECK(t.vertices == 7);
  CHECK(t.watertight());
  CHECK_FALSE(t.manifold());
}

TEST_CASE("mesh: degenerate faces are counted and otherwise ignored") {
  Mesh m = octahedron();
  m.faces.conservativeResize(10, 3);
  m.faces.row(8) << 0, 0, 1;
  m.faces.row(9) << 2, 3, 2;
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.degenerateFaces == 2);
  CHECK(t.faces == 10);
  CHECK(t.edges == 12);
  CHECK(t.eulerCharacteristic == 2);
  CHECK(t.watertight());
}

TEST_CASE("mesh: an out-of-range index is an InvalidArgument naming the face") {
  Mesh m = octahedron();
  m.faces(5, 2) = 6;
  for (int which = 0; which < 3; ++which) {
    CAPTURE(which);
    try {
      if (which == 0) (void)analyzeTopology(m);
      if (which == 1) (void)signedVolume(m);
      if (which == 2) (void)surfaceArea(m);
      FAIL("no exception");
    } catch (const InvalidArgument& e) {
      const std::string message = e.what();
      CHECK(message.find("face 5") != std::string::npos);
      CHECK(message.find("index 6") != std::string::npos);
    }
  }
  m.faces(5, 2) = -1;
  CHECK_THROWS_AS(analyzeTopology(m), InvalidArgument);
}

TEST_CASE("mesh: an empty mesh has empty topology") {
  const Mesh m;
  const MeshTopology t = analyzeTopology(m);
  CHECK(t.vertices == 0);
  CHECK(t.edges == 0);
  CHECK(t.components == 0);
  CHECK(t.eulerCharacteristic == 0);
  CHECK(signedVolume(m) == 0.0);
  CHECK(surfaceArea(m) == 0.0);
}

}  // TEST_SUITE
