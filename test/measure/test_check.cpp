// checkMesh on generated meshes: a closed sphere, a torus, a hole, a flipped face, an inside-out
// sphere, two components, overlapping spheres and hand-made triangle pairs (crossing, touching,
// sharing a vertex or an edge, folded, duplicate), and shared data meshes when present.
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <cmath>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

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

/// Splits the edge between face 0's first two corners a, b at a + t·(b − a): the two new triangles at a
/// are needles with an angle of about t·|ab|/|ac| radians; the mesh stays closed and manifold.
Mesh splitFirstEdge(const Mesh& m, double t) {
  const std::int32_t a = m.faces(0, 0), b = m.faces(0, 1);
  Mesh r = m;
  const auto mid = static_cast<std::int32_t>(m.vertices.rows());
  r.vertices.conservativeResize(mid + 1, 3);
  r.vertices.row(mid) = m.vertices.row(a) + t * (m.vertices.row(b) - m.vertices.row(a));
  std::vector<std::array<std::int32_t, 3>> faces;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    const std::array<std::int32_t, 3> v = {m.faces(f, 0), m.faces(f, 1), m.faces(f, 2)};
    bool split = false;
    for (int k = 0; k < 3 && !split; ++k) {
      const std::int32_t p = v[static_cast<std::size_t>(k)], q = v[static_cast<std::size_t>((k + 1) % 3)];
      const std::int32_t o = v[static_cast<std::size_t>((k + 2) % 3)];
      if ((p == a && q == b) || (p == b && q == a)) {
        faces.push_back({p, mid, o});
        faces.push_back({mid, q, o});
        split = true;
      }
    }
    if (!split) faces.push_back(v);
  }
  r.faces.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (std::size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) r.faces(static_cast<Eigen::Index>(f), k) = faces[f][static_cast<std::size_t>(k)];
  }
  return r;
}

/// float32Degenerate's rule as documented, computed only on the rounded corners (the library decides most
/// triangles from the double corners first; the two must agree everywhere).
bool roundedRule(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3f fa = a.cast<float>(), fb = b.cast<float>(), fc = c.cast<float>();
  if (fa == fb || fb == fc || fa == fc) return true;
  const Eigen::Vector3f n = (fb - fa).cross(fc - fa);
  if (n.x() == 0.0f && n.y() == 0.0f && n.z() == 0.0f) return true;
  const Eigen::Vector3d da = fa.cast<double>(), db = fb.cast<double>(), dc = fc.cast<double>();
  const double longest2 = std::max({(db - da).squaredNorm(), (dc - da).squaredNorm(), (dc - db).squaredNorm()});
  return !((db - da).cross(dc - da).norm() > 1e-12 * longest2);
}

/// triangleQuality as it states its counts: every face's smallest angle by minAngleDegrees (the library
/// takes the arc tangent only where the tangent cannot decide; the two must agree everywhere).
TriangleQuality statedQuality(const Mesh& mesh, double sliverAngle) {
  TriangleQuality q;
  q.sliverAngle = sliverAngle;
  q.faces = static_cast<std::size_t>(mesh.faces.rows());
  double minAngle = std::numeric_limits<double>::infinity(), shortest = std::numeric_limits<double>::infinity();
  for (Eigen::Index i = 0; i < mesh.faces.rows(); ++i) {
    const std::int32_t ia = mesh.faces(i, 0), ib = mesh.faces(i, 1), ic = mesh.faces(i, 2);
    const Eigen::Vector3d a = mesh.vertices.row(ia), b = mesh.vertices.row(ib), c = mesh.vertices.row(ic);
    const bool repeated = ia == ib || ib == ic || ia == ic;
    if (!repeated) shortest = std::min({shortest, (b - a).norm(), (c - b).norm(), (a - c).norm()});
    const bool degenerate = repeated || float32Degenerate(a, b, c);
    const double angle = repeated ? 0.0 : minAngleDegrees(a, b, c);
    if (degenerate) {
      ++q.float32DegenerateFaces;
      if (q.firstFloat32DegenerateFace < 0) q.firstFloat32DegenerateFace = i;
    } else {
      q.slivers += angle < sliverAngle ? 1 : 0;
      if (angle < minAngle) {
        minAngle = angle;
        q.worstFace = i;
      }
    }
    const double counted = degenerate ? 0.0 : angle;
    q.below1 += counted < 1.0 ? 1 : 0;
    q.below5 += counted < 5.0 ? 1 : 0;
    q.below10 += counted < 10.0 ? 1 : 0;
  }
  q.minAngle = std::isfinite(minAngle) ? minAngle : 0.0;
  q.shortestEdge = std::isfinite(shortest) ? shortest : 0.0;
  return q;
}

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
  SUBCASE("nearly coplanar triangles side by side") {
    // Two faces of cube_24k's zero mesh (float32, on the cube's face z = -0.5), one cell's diagonal apart:
    // each has corners within the tolerance of the other's plane, but the planes are not the same, and
    // their common line lay along the cells' row. The intervals on that line met; the faces do not.
    const std::array<double, 9> a{-5.728974201701931e-07, 0.023436926305294037, -0.5000005960464478,
                                  -7.550912073384097e-07, 0.02734375,           -0.5000007748603821,
                                  0.00390625,             0.02734375,           -0.5000007748603821};
    const std::array<double, 9> b{0.00390625,           0.02343691885471344,  -0.5000005960464478,
                                  0.007811714429408312, 0.02734375,           -0.5000007748603821,
                                  0.007811908610165119, 0.023436907678842545, -0.5000005960464478};
    CHECK(intersections(soup({a, b})) == 0);
    // The second moved by 1.5 cells along x: now they overlap.
    std::array<double, 9> c = b;
    for (int k = 0; k < 3; ++k) c[3 * k] -= 0.006;
    CHECK(intersections(soup({a, c})) == 1);
    // Planes at a tiny angle: a face lying just above the other, and one passing through it.
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{0.2, 0.2, 1e-9, 1, 0.2, 1e-9, 0.2, 1, 2e-9}}})) == 0);
    CHECK(intersections(soup({{{0, 0, 0, 2, 0, 0, 0, 2, 0}}, {{0.2, 0.2, -1e-9, 1, 0.2, 1e-9, 0.2, 1, 1e-9}}})) == 1);
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
    // A wedge over the other, tipped off its plane to one side (decided from the plane distances when they
    // exceed 1e-4 of the edges, by the sector test below that): touching at the vertex only. Lying in the
    // plane it overlaps; with its corners on both sides it passes through.
    for (const double tip : {1e-2, 1e-3, 1e-5, 1e-7}) {
      CAPTURE(tip);
      CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 1, 0.5, tip, 0.5, 1, tip}}})) == 0);
      CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 1, 0.5, -tip, 0.5, 1, -tip}}})) == 0);
      CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 1, 0.5, tip, 0.5, 1, -tip}}})) == 1);
    }
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 1, 0.5, 0, 0.5, 1, 0}}})) == 1);
  }
  SUBCASE("pairs sharing an edge, and duplicates") {
    // A dihedral angle: fine. Flat and unfolded: fine. Folded onto each other: intersecting.
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{1, 0, 0, 0, 0, 0, 0.3, 0, 1}}})) == 0);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{1, 0, 0, 0, 0, 0, 0.3, -1, 0}}})) == 0);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{1, 0, 0, 0, 0, 0, 0.3, 0.5, 0}}})) == 1);
    CHECK(intersections(soup({{{0, 0, 0, 1, 0, 0, 0, 1, 0}}, {{0, 0, 0, 0, 1, 0, 1, 0, 0}}})) == 1);
  }
}

TEST_CASE("check: the pair search finds the pairs that testing every pair finds") {
  // Two overlapping spheres with jittered vertices (folds and crossings within each, crossings between
  // them), a few faces repeated: every pair of faces is also tested alone, as a two-face mesh (whose
  // vertices are welded by position as in the whole mesh), and the two lists must agree.
  Mesh m = testing::concatenate(icosphere(2, 1.0), icosphere(2, 0.9, Eigen::RowVector3d(0.6, 0.1, 0.0)));
  std::uint64_t state = 12345;
  const auto uniform = [&state] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(state >> 11) / 9007199254740992.0 - 0.5;
  };
  for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
    for (int c = 0; c < 3; ++c) m.vertices(v, c) += 0.12 * uniform();
  }
  const Eigen::Index n0 = m.faces.rows();
  m.faces.conservativeResize(n0 + 3, 3);
  for (Eigen::Index k = 0; k < 3; ++k) m.faces.row(n0 + k) = m.faces.row(17 * k);
  CheckOptions all;
  all.listedPairs = std::numeric_limits<std::size_t>::max();
  const SelfIntersections found = findSelfIntersections(m, all);
  REQUIRE(found.complete);
  std::vector<std::pair<std::int64_t, std::int64_t>> brute;
  for (Eigen::Index i = 0; i < m.faces.rows(); ++i) {
    for (Eigen::Index j = i + 1; j < m.faces.rows(); ++j) {
      Mesh two;
      two.vertices.resize(6, 3);
      two.faces.resize(2, 3);
      for (int k = 0; k < 3; ++k) {
        two.vertices.row(k) = m.vertices.row(m.faces(i, k));
        two.vertices.row(3 + k) = m.vertices.row(m.faces(j, k));
      }
      two.faces << 0, 1, 2, 3, 4, 5;
      if (findSelfIntersections(two, all).count > 0) brute.emplace_back(i, j);
    }
  }
  CHECK(brute.size() > 50);  // the jitter folds and crosses faces: the test has pairs to find
  CHECK(found.count == brute.size());
  CHECK(found.pairs == brute);
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

TEST_CASE("check: a triangle degenerate in float32 is an error, slivers above the share limit too") {
  // Away from the origin: no coordinate near 0, where float32 is fine enough to keep 1e-10 apart.
  const Mesh sphere = icosphere(3, 1.0, Eigen::RowVector3d(2.0, 3.0, 4.0));
  const MeshCheck clean = checkMesh(sphere);
  CHECK(clean.quality.float32DegenerateFaces == 0);
  CHECK(clean.quality.slivers == 0);
  CHECK(clean.quality.below10 == 0);
  CHECK(clean.quality.minAngle > 40.0);
  CHECK(clean.valid());
  SUBCASE("float32-degenerate: two corners 1e-9 apart, distinct in double, one point in float32") {
    const Mesh m = splitFirstEdge(sphere, 1e-9);
    const MeshCheck c = checkMesh(m);
    CHECK(c.watertight);
    CHECK(c.manifold);
    CHECK(c.oriented);
    CHECK(c.validation.degenerateFaces() == 0);  // fine in double
    CHECK(c.quality.float32DegenerateFaces == 2);
    CHECK(c.quality.firstFloat32DegenerateFace >= 0);
    CHECK(c.quality.below1 >= 2);
    CHECK_FALSE(c.valid());
    CHECK(float32Degenerate(m.vertices.row(m.faces(0, 0)), m.vertices.row(m.faces(0, 1)), m.vertices.row(m.faces(0, 2))));
    // Collinear corners with distinct float32 coordinates are degenerate too.
    CHECK(float32Degenerate(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1), Eigen::Vector3d(2, 2, 2)));
    CHECK_FALSE(float32Degenerate(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1e-3, 0)));
  }
  SUBCASE("slivers: two needles of about 0.006 degrees in 1282 triangles") {
    const Mesh m = splitFirstEdge(sphere, 1e-4);
    MeshCheck c = checkMesh(m);
    CHECK(c.quality.float32DegenerateFaces == 0);
    CHECK(c.quality.slivers == 2);
    CHECK(c.quality.below1 == 2);
    CHECK(c.quality.below5 == 2);
    CHECK(c.quality.minAngle < 0.01);
    CHECK(c.quality.minAngle > 0.0);
    CHECK(c.quality.worstFace >= 0);
    CHECK(c.tooManySlivers);  // 2 > 0.1% of 1282
    CHECK_FALSE(c.valid());
    CheckOptions lenient;
    lenient.maxSliverShare = 0.01;
    c = checkMesh(m, lenient);
    CHECK_FALSE(c.tooManySlivers);
    CHECK(c.valid());
    CheckOptions tiny;
    tiny.sliverAngle = 0.001;  // the needles are above it
    CHECK(checkMesh(m, tiny).quality.slivers == 0);
    CHECK(minAngleDegrees(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0)) ==
          doctest::Approx(45.0));
  }
}

TEST_CASE("check: triangle quality counts as its angles state, at the bounds to the last bits too") {
  // A soup of isosceles needles whose smallest angle is each bound (1, 5, 10 degrees, the sliver angles)
  // times 1 + j·2⁻⁵², j = −64 … 64, and the same angles a relative 1e-9 either side (where the library
  // turns from the tangent to the arc tangent), in several orientations and sizes, plus random
  // triangles, near-degenerate ones and repeated corners; the minimum falls in steps (its face first).
  std::mt19937_64 rng(20261206);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> corners;
  const auto add = [&corners](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    corners.push_back(a);
    corners.push_back(b);
    corners.push_back(c);
  };
  for (int r = 0; r < 3000; ++r) add(Eigen::Vector3d(u(rng), u(rng), u(rng)), Eigen::Vector3d(u(rng), u(rng), u(rng)),
                                     Eigen::Vector3d(u(rng), u(rng), u(rng)));
  for (const double bound : {0.5, 1.0, 3.0, 5.0, 10.0, 20.0, 60.0}) {
    for (int j = -64; j <= 64; ++j) {
      for (const double rel : {0.0, 1e-9, -1e-9, 1.0001e-9, -0.9999e-9}) {
        const double theta = bound * (1.0 + j * std::ldexp(1.0, -52) + rel) * M_PI / 180.0;
        const double size = std::pow(10.0, 3.0 * u(rng));
        const Eigen::Vector3d origin(u(rng), u(rng), u(rng));
        // Unit legs along two orthonormal directions d1, d2 of a random frame: the angle at the apex.
        const Eigen::Vector3d d1 = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
        const Eigen::Vector3d d2 = d1.cross(Eigen::Vector3d(u(rng), u(rng), u(rng))).normalized();
        add(origin, origin + size * d1, origin + size * (std::cos(theta) * d1 + std::sin(theta) * d2));
      }
    }
  }
  // Needles at a bound where the arc tangent and the tangent disagree about "below" (rounding: about one
  // in a thousand within 2⁻⁴⁴ of 5 and 10 degrees): a test of the tangent alone would count them wrong.
  std::size_t disagreeing = 0;
  for (const double bound : {1.0, 3.0, 5.0, 10.0, 20.0}) {
    const double t = std::tan(bound * M_PI / 180.0);
    int found = 0;
    for (int tries = 0; tries < 400000 && found < 16; ++tries) {
      const double theta = bound * (1.0 + std::ldexp(u(rng), -44)) * M_PI / 180.0;
      const Eigen::Vector3d b(1.0 + 0.3 * u(rng), 0, 0), c(std::cos(theta), std::sin(theta), 0);
      const double cross = b.cross(c).norm(), dot = b.dot(c);
      if ((std::atan2(cross, dot) * (180.0 / M_PI) < bound) == (cross / dot < t)) continue;
      add(Eigen::Vector3d(0, 0, 0), b, c);
      ++found;
    }
    disagreeing += static_cast<std::size_t>(found);
  }
  CHECK(disagreeing >= 16);
  for (int r = 0; r < 200; ++r) {  // decreasing needles: every one a new minimum
    const double theta = 30.0 * std::pow(0.9, r) * M_PI / 180.0;
    add(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(std::cos(theta), std::sin(theta), 0));
  }
  for (int r = 0; r < 64; ++r) {  // then smaller by a relative 5e-10 each: new minima within any margin
    const double theta = 30.0 * std::pow(0.9, 200) * (1.0 - 5e-10 * (r + 1)) * M_PI / 180.0;
    add(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(std::cos(theta), std::sin(theta), 0));
  }
  add(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(2, 1e-12, 0));  // flat in float32
  Mesh m;
  m.vertices.resize(static_cast<Eigen::Index>(corners.size()), 3);
  m.faces.resize(static_cast<Eigen::Index>(corners.size() / 3), 3);
  for (std::size_t i = 0; i < corners.size(); ++i) m.vertices.row(static_cast<Eigen::Index>(i)) = corners[i].transpose();
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) m.faces.row(f) << 3 * f, 3 * f + 1, 3 * f + 2;
  m.faces(1, 2) = m.faces(1, 1);  // a repeated corner
  for (const double sliver : {0.0, 0.5, 1.0, 3.0, 20.0, 60.0}) {
    CAPTURE(sliver);
    const TriangleQuality got = triangleQuality(m, sliver), want = statedQuality(m, sliver);
    CHECK(got.slivers == want.slivers);
    CHECK(got.below1 == want.below1);
    CHECK(got.below5 == want.below5);
    CHECK(got.below10 == want.below10);
    CHECK(got.minAngle == want.minAngle);
    CHECK(got.worstFace == want.worstFace);
    CHECK(got.float32DegenerateFaces == want.float32DegenerateFaces);
    CHECK(got.firstFloat32DegenerateFace == want.firstFloat32DegenerateFace);
    CHECK(got.shortestEdge == want.shortestEdge);
    CHECK(want.below1 > 0);
    CHECK(want.below10 > want.below5);
  }
  // minAngleBelow (the cleaning's and the projection's per-face test) says what the arc tangent says, at
  // the same bounds, on the same faces (the needles within 2^-44 of a bound included).
  std::size_t wrong = 0, below = 0, tested = 0;
  for (const double bound : {0.5, 1.0, 3.0, 5.0, 10.0, 20.0, 60.0, 0.0, 90.0, 120.0}) {
    for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
      const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
                            c = m.vertices.row(m.faces(f, 2));
      const bool want = minAngleDegrees(a, b, c) < bound;
      wrong += minAngleBelow(a, b, c, bound) != want ? 1 : 0;
      below += want ? 1 : 0;
      ++tested;
    }
  }
  CHECK(wrong == 0);
  CHECK(below > tested / 10);
  CHECK(below < tested - tested / 10);
}

TEST_CASE("check: float32Degenerate agrees with its rule on the rounded corners, near the boundary too") {
  std::mt19937_64 rng(20261205);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::size_t degenerate = 0, mismatches = 0;
  const std::size_t n = 400000;
  for (std::size_t i = 0; i < n; ++i) {
    // Offsets from 0 to 1e8, edges from 1e-25 to 1e5, some nearly collinear (the third edge a multiple
    // of the first plus t times another, t from 1e-20 to 1), some a float ulp apart, some NaN or infinite.
    const double offset = i % 3 == 0 ? 0.0 : std::pow(10.0, 4.0 + 4.0 * u(rng));
    const double scale = std::pow(10.0, -10.0 + 15.0 * u(rng));
    const Eigen::Vector3d a = offset * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Vector3d d1(u(rng), u(rng), u(rng));
    Eigen::Vector3d d2(u(rng), u(rng), u(rng));
    const double t = std::pow(10.0, -10.0 + 10.0 * u(rng));
    if (i % 2 == 0) d2 = u(rng) * d1 + t * d2;
    const Eigen::Vector3d b = a + scale * d1;
    Eigen::Vector3d c = a + scale * d2;
    if (i % 11 == 0) {
      c = b;
      c[static_cast<Eigen::Index>(i % 3)] = std::nextafter(static_cast<float>(b[static_cast<Eigen::Index>(i % 3)]), 1e30f);
    }
    Eigen::Vector3d a2 = a;
    if (i % 97 == 0) a2.x() = i % 2 == 0 ? std::numeric_limits<double>::quiet_NaN() : std::numeric_limits<double>::infinity();
    const bool rule = roundedRule(a2, b, c);
    degenerate += rule ? 1 : 0;
    mismatches += rule != float32Degenerate(a2, b, c) ? 1 : 0;
  }
  CHECK(mismatches == 0);
  // Both kinds occur, many of each.
  CHECK(degenerate > n / 10);
  CHECK(degenerate < n - n / 10);
}

}  // TEST_SUITE
