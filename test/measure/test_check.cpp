// checkMesh on generated meshes: a closed sphere, a torus, a hole, a flipped face, an inside-out
// sphere, two components, overlapping spheres and hand-made triangle pairs (crossing, touching,
// sharing a vertex or an edge, folded, duplicate), and shared data meshes when present.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "data.hpp"
#include "duplexfit/io.hpp"
#include "core/mesh_shapes.hpp"
#include "duplexfit/measure.hpp"
#include "measure/measure_shapes.hpp"

namespace {

using namespace duplexfit;
using testing::icosphere;
using testing::soup;

Mesh withoutFace(const Mesh& m, Eigen::Index f) {
  Mesh r = m;
  r.faces.resize(m.faces.rows() - 1, 3);
  r.faces.topRows(f) = m.faces.topRows(f);
  r.faces.bottomRows(m.faces.rows() - f - 1) = m.faces.bottomRows(m.faces.rows() - f - 1);
  return r;
}

std::size_t intersections(const Mesh& m) { return checkMesh(m).selfIntersections; }

}  // namespace

TEST_SUITE("measure") {

TEST_CASE("check: a closed sphere is a valid genus-0 mesh") {
  const Mesh m = icosphere(3, 1.0);
  const MeshCheck c = checkMesh(m);
  CHECK(c.watertight);
  CHECK(c.manifold);
  CHECK(c.oriented);
  CHECK(c.outward);
  CHECK(c.topology.components == 1);
  CHECK(c.topology.eulerCharacteristic == 2);
  CHECK(c.genusKnown);
  CHECK(c.genus == 0);
  CHECK(c.boundaryLoops == 0);
  CHECK(c.selfIntersectionsChecked);
  CHECK(c.selfIntersections == 0);
  CHECK(c.validation.degenerateFaces() == 0);
  CHECK(c.valid());
  CHECK(c.signedVolume == doctest::Approx(4.0 / 3.0 * M_PI).epsilon(0.05));
  CHECK(c.area == doctest::Approx(4.0 * M_PI).epsilon(0.05));
  CheckOptions o;
  o.selfIntersections = false;
  CHECK_FALSE(checkMesh(m, o).selfIntersectionsChecked);
}

TEST_CASE("check: a torus has genus 1") {
  const MeshCheck c = checkMesh(testing::torus(32, 16, 1.0, 0.35));
  CHECK(c.topology.eulerCharacteristic == 0);
  CHECK(c.genusKnown);
  CHECK(c.genus == 1);
  CHECK(c.selfIntersections == 0);
  CHECK(c.valid());
}

TEST_CASE("check: a hole, a flipped face, an inside-out mesh, two components") {
  const Mesh sphere = icosphere(2, 1.0);
  SUBCASE("hole") {
    const MeshCheck c = checkMesh(withoutFace(withoutFace(sphere, 10), 200));
    CHECK_FALSE(c.watertight);
    CHECK(c.boundaryLoops == 2);
    CHECK(c.topology.boundaryEdges == 6);
    CHECK(c.genusKnown);
    CHECK(c.genus == 0);
    CHECK_FALSE(c.valid());
  }
  SUBCASE("flipped face") {
    Mesh m = sphere;
    std::swap(m.faces(5, 1), m.faces(5, 2));
    const MeshCheck c = checkMesh(m);
    CHECK(c.watertight);
    CHECK_FALSE(c.oriented);
    CHECK(c.topology.inconsistentEdges == 3);
    CHECK_FALSE(c.genusKnown);
    CHECK(c.selfIntersections == 0);
    CHECK_FALSE(c.valid());
  }
  SUBCASE("inside out") {
    Mesh m = sphere;
    m.faces.col(1).swap(m.faces.col(2));
    const MeshCheck c = checkMesh(m);
    CHECK(c.oriented);
    CHECK_FALSE(c.outward);
    CHECK(c.signedVolume < 0.0);
    CHECK_FALSE(c.valid());
  }
  SUBCASE("two components, one of them a torus") {
    const Mesh m = testing::concatenate(sphere, testing::torus(16, 8, 1.0, 0.3));
    // concatenate shifts the second mesh's indices; move the torus away from the sphere.
    Mesh moved = m;
    moved.vertices.bottomRows(16 * 8).col(0).array() += 5.0;
    const MeshCheck c = checkMesh(moved);
    CHECK(c.topology.components == 2);
    CHECK(c.topology.eulerCharacteristic == 2);
    CHECK(c.genus == 1);
    CHECK(c.selfIntersections == 0);
    CHECK(c.valid());
  }
}

TEST_CASE("check: self-intersections of overlapping spheres and of triangle pairs") {
  SUBCASE("two overlapping spheres intersect, two apart do not") {
    const Mesh a = icosphere(2, 1.0), b = icosphere(2, 1.0, Eigen::RowVector3d(0.7, 0.2, 0.1));
    const MeshCheck c = checkMesh(testing::concatenate(a, b));
    CHECK(c.selfIntersections > 10);
    CHECK_FALSE(c.valid());
    CHECK_FALSE(c.pairs.empty());
    CHECK(c.pairs.size() <= 20);
    CHECK(c.pairs.front().first < c.pairs.front().second);
    const Mesh far = icosphere(2, 1.0, Eigen::RowVector3d(2.5, 0, 0));
    CHECK(intersections(testing::concatenate(a, far)) == 0);
  }
  SUBCASE("crossing, touching and separate triangles without shared vertices") {
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{0.5, 0.5, -1, 0.5, 0.5, 1, 1, 0.2, 0}}})) == 1);
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{0.5, 0.5, 0.1, 0.5, 0.5, 1, 1, 0.2, 0.1}}})) == 0);
    // A corner touching the other's interior.
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{0.5, 0.5, 0, 0.5, 0.5, 1, 1, 0.2, 1}}})) == 1);
    // Coplanar: overlapping, nested, disjoint.
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{1, 1, 0, -1, 0.5, 0, 1, -1, 0}}})) == 1);
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{0.1, 0.1, 0, 0.5, 0.1, 0, 0.1, 0.5, 0}}})) == 1);
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{2, 2, 0, 3, 2, 0, 2, 3, 0}}})) == 0);
  }
  SUBCASE("pairs sharing a vertex") {
    // Positions shared (soup vertices are separate indices, welded by position).
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, -1, 0, 0, 0, 0, 1}}})) == 0);
    // The second triangle passes through the first beyond the shared corner.
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 1, 1, 1, 1, 1, -1}}})) == 1);
    // Coplanar fans: adjacent wedges touch along a ray only; overlapping wedges intersect.
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 0, 1, 0, -1, -0.01, 0}}})) == 0);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 1, 1, 0, -1, 2, 0}}})) == 1);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 2, 0, 0, 0, 2, 0}}})) == 1);
  }
  SUBCASE("pairs sharing an edge, and duplicates") {
    // A dihedral angle: fine. Flat and unfolded: fine. Folded onto each other: intersecting.
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{1, 0, 0, 0, 0, 0, 0.3, 0, 1}}})) == 0);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{1, 0, 0, 0, 0, 0, 0.3, -1, 0}}})) == 0);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{1, 0, 0, 0, 0, 0, 0.3, 0.5, 0}}})) == 1);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 0, 1, 0, 1, 0, 0}}})) == 1);
  }
}

TEST_CASE("check: shared data meshes match their manifest") {
  DUPLEXFIT_SHARED_DATA_DIR(dir);
  struct Expect {
    const char* file;
    long long euler, genus;
  };
  for (const Expect e : {Expect{"meshes/fandisk.ply", 2, 0}, Expect{"meshes/eight.ply", -2, 2}}) {
    INFO(e.file);
    const MeshCheck c = checkMesh(readMesh(dir + "/" + e.file));
    CHECK(c.watertight);
    CHECK(c.manifold);
    CHECK(c.oriented);
    CHECK(c.outward);
    CHECK(c.topology.components == 1);
    CHECK(c.topology.eulerCharacteristic == e.euler);
    CHECK(c.genus == e.genus);
    CHECK(c.selfIntersections == 0);
  }
}

}  // TEST_SUITE
