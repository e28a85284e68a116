// Mesh input: sampleMeshCloud (counts from each rule, per-face counts against the area, uniformity inside
// a face, samples on their faces with their faces' normals, inside-out, open, non-manifold, inconsistent
// and degenerate meshes, errors that name the source) and detectInputKind.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "core/mesh_shapes.hpp"
#include "measure/measure_shapes.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh_sampling.hpp"
#include "io_test_util.hpp"

using namespace duplexfit;

namespace {

Eigen::Vector3d corner(const Mesh& m, Eigen::Index f, int k) { return m.vertices.row(m.faces(f, k)).transpose(); }

double faceArea(const Mesh& m, Eigen::Index f) {
  return 0.5 * (corner(m, f, 1) - corner(m, f, 0)).cross(corner(m, f, 2) - corner(m, f, 0)).norm();
}

Eigen::Vector3d faceNormal(const Mesh& m, Eigen::Index f) {
  return (corner(m, f, 1) - corner(m, f, 0)).cross(corner(m, f, 2) - corner(m, f, 0)).normalized();
}

/// The mesh with every face's orientation reversed.
Mesh reversed(Mesh m) {
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) std::swap(m.faces(f, 1), m.faces(f, 2));
  return m;
}

/// The mesh without the listed faces.
Mesh without(const Mesh& m, std::initializer_list<Eigen::Index> drop) {
  std::vector<char> keep(static_cast<std::size_t>(m.faces.rows()), 1);
  for (const Eigen::Index f : drop) keep[static_cast<std::size_t>(f)] = 0;
  Mesh r = m;
  Eigen::Index row = 0;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    if (keep[static_cast<std::size_t>(f)]) r.faces.row(row++) = m.faces.row(f);
  }
  r.faces.conservativeResize(row, 3);
  return r;
}

/// The unit cube with each triangle split into three at the off-centre point of barycentric coordinates
/// (0.7, 0.2, 0.1): 36 faces of areas 0.35, 0.1 and 0.05, so area-proportional counts differ from face to face.
Mesh unevenCube() {
  const Mesh c = testing::cube();
  Mesh m;
  m.vertices.resize(8 + 12, 3);
  m.vertices.topRows(8) = c.vertices;
  m.faces.resize(3 * 12, 3);
  for (Eigen::Index f = 0; f < 12; ++f) {
    const std::int32_t a = c.faces(f, 0), b = c.faces(f, 1), d = c.faces(f, 2);
    const auto p = static_cast<std::int32_t>(8 + f);
    m.vertices.row(p) = 0.7 * c.vertices.row(a) + 0.2 * c.vertices.row(b) + 0.1 * c.vertices.row(d);
    m.faces.row(3 * f + 0) << p, b, d;
    m.faces.row(3 * f + 1) << a, p, d;
    m.faces.row(3 * f + 2) << a, b, p;
  }
  return m;
}

/// Barycentric coordinates of p in face f (p assumed in its plane).
Eigen::Vector3d barycentric(const Mesh& m, Eigen::Index f, const Eigen::Vector3d& p) {
  const Eigen::Vector3d a = corner(m, f, 0), b = corner(m, f, 1), c = corner(m, f, 2);
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double wa = (c - b).cross(p - b).dot(n) / n.squaredNorm();
  const double wb = (a - c).cross(p - c).dot(n) / n.squaredNorm();
  return {wa, wb, 1.0 - wa - wb};
}

/// Every sample lies on its face (in the plane, barycentric coordinates in [0, 1]) and carries the face's
/// normal times `sign`.
void checkOnFaces(const Mesh& m, const MeshSampleResult& s, double sign = 1.0) {
  const Points& p = s.points.positions();
  const Points& n = s.points.normals();
  REQUIRE(s.faces.size() == s.points.size());
  std::size_t off = 0, badNormal = 0;
  for (std::size_t i = 0; i < s.points.size(); ++i) {
    const auto f = static_cast<Eigen::Index>(s.faces[i]);
    const auto row = static_cast<Eigen::Index>(i);
    const Eigen::Vector3d q = p.row(row).transpose();
    const Eigen::Vector3d fn = faceNormal(m, f);
    const double height = std::abs((q - corner(m, f, 0)).dot(fn));
    const Eigen::Vector3d w = barycentric(m, f, q);
    if (height > 1e-12 || w.minCoeff() < -1e-12 || w.maxCoeff() > 1.0 + 1e-12) ++off;
    if (!(Eigen::Vector3d(n.row(row).transpose()).dot(sign * fn) > 1.0 - 1e-12)) ++badNormal;
  }
  CHECK(off == 0);
  CHECK(badNormal == 0);
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

bool anyContains(const std::vector<std::string>& lines, const std::string& part) {
  for (const std::string& l : lines) {
    if (contains(l, part)) return true;
  }
  return false;
}

/// The message of the InvalidArgument sampleMeshCloud throws ("" when it does not throw).
std::string samplingError(const Mesh& m, const MeshSampleOptions& o, const std::string& source = "part.stl") {
  try {
    (void)sampleMeshCloud(m, o, source);
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_SUITE("io") {
  TEST_CASE("mesh sampling: the count follows --sample-points, --sample-spacing or the default rule") {
    const Mesh cube = testing::cube();  // area 6, largest side 1
    MeshSampleOptions o;
    o.points = 1234;
    MeshSampleResult s = sampleMeshCloud(cube, o, "cube.stl");
    CHECK(s.points.size() == 1234);
    CHECK(s.report.samples == 1234);
    CHECK(s.report.densityRule == "points");
    CHECK(s.report.area == doctest::Approx(6.0));
    CHECK(s.report.spacing == doctest::Approx(std::sqrt(6.0 / 1234.0)));
    CHECK(s.report.warnings.empty());
    CHECK(s.report.topology.watertight());
    CHECK_FALSE(s.report.flipped);
    CHECK(s.report.signedVolume == doctest::Approx(1.0));

    o = {};
    o.spacing = 0.05;
    s = sampleMeshCloud(cube, o, "cube.stl");
    CHECK(s.points.size() == 2400);  // ⌈6 / 0.05²⌉
    CHECK(s.report.densityRule == "spacing");

    o = {};
    s = sampleMeshCloud(cube, o, "cube.stl");
    CHECK(s.report.densityRule == "default");
    CHECK(s.report.requestedSpacing == doctest::Approx(1.0 / 150.0));
    CHECK(s.points.size() == 135000);  // ⌈6 / (1/150)²⌉
    CHECK_FALSE(s.report.clamped);

    // The default rule is scale-free: the same count for the cube 1000 times larger.
    Mesh big = cube;
    big.vertices *= 1000.0;
    CHECK(sampleMeshCloud(big, o, "big.stl").points.size() == s.points.size());

    o.minPoints = 100;
    o.maxPoints = 500;
    s = sampleMeshCloud(cube, o, "cube.stl");
    CHECK(s.points.size() == 500);
    CHECK(s.report.clamped);
    CHECK(anyContains(s.report.warnings, "clamped"));

    // Deterministic: the same seed gives the same samples, another seed others.
    o = {};
    o.points = 300;
    const MeshSampleResult a = sampleMeshCloud(cube, o), b = sampleMeshCloud(cube, o);
    CHECK(a.points.positions() == b.points.positions());
    o.seed = 7;
    const MeshSampleResult c = sampleMeshCloud(cube, o);
    CHECK(c.points.positions() != a.points.positions());
  }

  TEST_CASE("mesh sampling: per-face counts follow the area, uniform inside a face, on the faces with face normals") {
    const Mesh m = unevenCube();
    double total = 0.0;
    for (Eigen::Index f = 0; f < m.faces.rows(); ++f) total += faceArea(m, f);
    REQUIRE(total == doctest::Approx(6.0));
    MeshSampleOptions o;
    o.points = 10007;
    const MeshSampleResult s = sampleMeshCloud(m, o, "uneven.obj");
    REQUIRE(s.points.size() == 10007);
    std::vector<std::size_t> count(static_cast<std::size_t>(m.faces.rows()), 0);
    for (const std::int64_t f : s.faces) ++count[static_cast<std::size_t>(f)];
    // Systematic sampling: every face gets its expected count rounded down or up.
    double worst = 0.0;
    for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
      const double expected = 10007.0 * faceArea(m, f) / total;
      worst = std::max(worst, std::abs(static_cast<double>(count[static_cast<std::size_t>(f)]) - expected));
    }
    CHECK(worst < 1.0);
    checkOnFaces(m, s);
    CHECK(s.report.warnings.empty());

    // Inside one triangle: its four midpoint sub-triangles (equal areas) get a quarter each.
    Mesh tri;
    tri.vertices.resize(3, 3);
    tri.vertices << 0, 0, 0, 2, 0, 0, 0.5, 1.5, 0;
    tri.faces.resize(1, 3);
    tri.faces << 0, 1, 2;
    o.points = 20000;
    const MeshSampleResult t = sampleMeshCloud(tri, o, "triangle.stl");
    int quarter[4] = {0, 0, 0, 0};
    for (Eigen::Index i = 0; i < t.points.positions().rows(); ++i) {
      const Eigen::Vector3d w = barycentric(tri, 0, t.points.positions().row(i).transpose());
      const int sub = w[0] > 0.5 ? 0 : w[1] > 0.5 ? 1 : w[2] > 0.5 ? 2 : 3;
      ++quarter[sub];
    }
    for (const int q : quarter) CHECK(std::abs(q - 5000) < 100);  // 2%; i.i.d. sampling would give ±1.2% s.d.
    // Open (one triangle): reported, not an error.
    CHECK(t.report.topology.boundaryEdges == 3);
    CHECK(t.report.open());
  }

  TEST_CASE("mesh sampling: an inside-out mesh has its normals flipped outward, and says so") {
    const Mesh sphere = testing::icosphere(2, 0.5);
    MeshSampleOptions o;
    o.points = 2000;
    const MeshSampleResult good = sampleMeshCloud(sphere, o, "sphere.stl");
    CHECK_FALSE(good.report.flipped);
    CHECK(good.report.signedVolume > 0.0);
    CHECK(good.report.warnings.empty());
    const Mesh inside = reversed(sphere);
    const MeshSampleResult s = sampleMeshCloud(inside, o, "inside.stl");
    CHECK(s.report.flipped);
    CHECK(s.report.signedVolume < 0.0);
    REQUIRE(s.report.warnings.size() == 1);
    CHECK(contains(s.report.warnings[0], "inside.stl"));
    CHECK(contains(s.report.warnings[0], "inside out"));
    checkOnFaces(inside, s, -1.0);  // the reversed faces' normals, negated
    std::size_t inward = 0;
    for (Eigen::Index i = 0; i < s.points.positions().rows(); ++i) {
      if (s.points.normals().row(i).dot(s.points.positions().row(i)) <= 0.0) ++inward;
    }
    CHECK(inward == 0);
  }

  TEST_CASE("mesh sampling: an open or non-manifold mesh is a warning naming the file and counts; --strict an error") {
    const Mesh cube = testing::cube();
    const Mesh open = without(cube, {2, 3});  // the side z = 1: a square hole, four boundary edges
    MeshSampleOptions o;
    o.points = 500;
    const MeshSampleResult s = sampleMeshCloud(open, o, "open.stl");
    CHECK(s.report.topology.boundaryEdges == 4);
    CHECK(s.report.open());
    CHECK(s.report.firstBoundaryFace >= 0);
    REQUIRE(s.report.warnings.size() == 1);
    CHECK(contains(s.report.warnings[0], "open.stl"));
    CHECK(contains(s.report.warnings[0], "4 boundary edge(s)"));
    CHECK(s.points.size() == 500);
    o.strict = true;
    const std::string e = samplingError(open, o, "open.stl");
    CHECK(contains(e, "open.stl"));
    CHECK(contains(e, "4 boundary edge(s)"));
    CHECK(contains(e, "--strict"));

    // A third face on the cube's edge (0, 1): a non-manifold edge.
    Mesh fin = cube;
    fin.vertices.conservativeResize(9, 3);
    fin.vertices.row(8) << 0.5, -1.0, -1.0;
    fin.faces.conservativeResize(13, 3);
    fin.faces.row(12) << 0, 1, 8;
    o.strict = false;
    const MeshSampleResult n = sampleMeshCloud(fin, o, "fin.obj");
    CHECK(n.report.topology.nonManifoldEdges == 1);
    CHECK(n.report.firstNonManifoldFace >= 0);
    CHECK(anyContains(n.report.warnings, "1 edge(s) shared by more than two faces"));
    o.strict = true;
    CHECK(contains(samplingError(fin, o, "fin.obj"), "fin.obj"));
  }

  TEST_CASE("mesh sampling: an inconsistently oriented mesh is an error unless re-oriented (or kept)") {
    Mesh cube = testing::cube();
    std::swap(cube.faces(5, 1), cube.faces(5, 2));  // one triangle turned over: three inconsistent edges
    MeshSampleOptions o;
    o.points = 600;
    const std::string e = samplingError(cube, o, "bad.stl");
    INFO(e);
    CHECK(contains(e, "bad.stl"));
    CHECK(contains(e, "not consistently oriented"));
    CHECK(contains(e, "3 edge(s)"));
    CHECK(contains(e, "faces "));
    CHECK(contains(e, "--mesh-reorient"));

    o.orientation = MeshOrientation::Reorient;
    const MeshSampleResult s = sampleMeshCloud(cube, o, "bad.stl");
    CHECK(s.report.topology.inconsistentEdges == 3);
    CHECK(s.report.reorientedFaces == 1);
    CHECK(s.report.inconsistentAfter == 0);
    CHECK_FALSE(s.report.flipped);
    CHECK(anyContains(s.report.warnings, "1 face(s) flipped"));
    const Eigen::RowVector3d centre(0.5, 0.5, 0.5);
    std::size_t inward = 0;
    for (Eigen::Index i = 0; i < s.points.positions().rows(); ++i) {
      if (s.points.normals().row(i).dot(s.points.positions().row(i) - centre) <= 0.0) ++inward;
    }
    CHECK(inward == 0);

    // Five of twelve triangles turned: the larger part (by area) keeps its orientation.
    Mesh five = testing::cube();
    for (const Eigen::Index f : {0, 3, 4, 9, 10}) std::swap(five.faces(f, 1), five.faces(f, 2));
    const MeshSampleResult r = sampleMeshCloud(five, o, "five.stl");
    CHECK(r.report.reorientedFaces == 5);
    CHECK(r.report.inconsistentAfter == 0);
    CHECK(r.report.signedVolume == doctest::Approx(1.0));

    // Keep: sampled as it is, with a warning (the caller re-estimates the normals).
    o.orientation = MeshOrientation::Keep;
    const MeshSampleResult k = sampleMeshCloud(cube, o, "bad.stl");
    CHECK(k.points.size() == 600);
    CHECK(anyContains(k.report.warnings, "sampled as they are"));
  }

  TEST_CASE("mesh sampling: no faces or zero area are errors naming the file; degenerate faces get no samples") {
    Mesh empty;
    empty.vertices = testing::cube().vertices;
    empty.faces.resize(0, 3);
    const std::string noFaces = samplingError(empty, {}, "empty.stl");
    CHECK(contains(noFaces, "empty.stl"));
    CHECK(contains(noFaces, "no faces"));

    Mesh flat;
    flat.vertices.resize(4, 3);
    flat.vertices << 0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0;  // collinear
    flat.faces.resize(3, 3);
    flat.faces << 0, 1, 2, 1, 2, 3, 0, 0, 3;
    const std::string zero = samplingError(flat, {}, "flat.stl");
    CHECK(contains(zero, "flat.stl"));
    CHECK(contains(zero, "zero area"));

    Mesh cube = testing::cube();
    cube.faces.conservativeResize(14, 3);
    cube.faces.row(12) << 0, 0, 1;  // repeated index
    cube.vertices.conservativeResize(9, 3);
    cube.vertices.row(8) << 0.5, 0.0, 0.0;  // on the edge (0, 1): a zero-area face
    cube.faces.row(13) << 0, 8, 1;
    MeshSampleOptions o;
    o.points = 3000;
    const MeshSampleResult s = sampleMeshCloud(cube, o, "cube.stl");
    CHECK(s.report.degenerateFaces == 2);
    CHECK(anyContains(s.report.warnings, "2 degenerate face(s)"));
    for (const std::int64_t f : s.faces) CHECK(f < 12);
    CHECK(s.points.size() == 3000);

    const Mesh tri = testing::tetrahedron(Eigen::RowVector3d::Zero());
    Mesh bad = tri;
    bad.faces(1, 2) = 9;
    CHECK(contains(samplingError(bad, {}, "bad.obj"), "bad.obj: face 1"));
    MeshSampleOptions both;
    both.points = 100;
    both.spacing = 0.1;
    CHECK(contains(samplingError(tri, both, "t.stl"), "not both"));
    MeshSampleOptions negative;
    negative.spacing = -0.1;
    CHECK(contains(samplingError(tri, negative, "t.stl"), "positive"));
    MeshSampleOptions tiny;
    tiny.spacing = 1e-6;
    CHECK(contains(samplingError(tri, tiny, "t.stl"), "limit"));
  }

  TEST_CASE("mesh input: detectInputKind tells meshes from clouds (STL, OBJ, PLY with faces)") {
    testing::TempDir dir("duplexfit-meshin");
    const Mesh m = testing::octahedron(0.5);
    writeMesh(dir.file("a.stl"), m);
    writeMesh(dir.file("a.obj"), m);
    writeMesh(dir.file("a.ply"), m);
    Points normals;
    Points p = m.vertices;
    normals = m.vertices.rowwise().normalized();
    writePointCloud(dir.file("c.ply"), PointSet(p, normals));
    testing::writeBytes(dir.file("c.xyz"), "0 0 0 0 0 1\n");
    testing::writeBytes(dir.file("f0.ply"),
                        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                        "element face 0\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n");
    CHECK(detectInputKind(dir.file("a.stl")) == InputKind::Mesh);
    CHECK(detectInputKind(dir.file("a.obj")) == InputKind::Mesh);
    CHECK(detectInputKind(dir.file("a.ply")) == InputKind::Mesh);
    CHECK(detectInputKind(dir.file("c.ply")) == InputKind::Cloud);
    CHECK(detectInputKind(dir.file("c.xyz")) == InputKind::Cloud);
    CHECK(detectInputKind(dir.file("f0.ply")) == InputKind::Cloud);  // a face element with no face
    CHECK_THROWS_AS(detectInputKind(dir.file("missing.ply")), IoError);
    CHECK(meshFormatOf("x.STL") == MeshFormat::Stl);
    CHECK(std::string(meshFormatName(meshFormatOf("x.obj"))) == "obj");
    CHECK(meshFormatOf("x.off") == MeshFormat::Auto);
  }
}
