// Measurements on generated meshes: the BVH against brute force (random soups with degenerate
// triangles), sampling (deterministic, area-uniform), Metro distances of concentric spheres within
// the chordal error bound, a mesh against itself, offset statistics and wrong-side shares, and
// validation errors that name the source and element.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>
#include <random>
#include <string>

#include "duplexfit/error.hpp"
#include "duplexfit/measure.hpp"
#include "measure/measure_shapes.hpp"

namespace {

using namespace duplexfit;
using testing::chordalError;
using testing::icosphere;

/// A random triangle soup on random shared vertices, with some degenerate triangles mixed in.
Mesh randomMesh(int vertices, int faces, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_int_distribution<int> pick(0, vertices - 1);
  Mesh m;
  m.vertices.resize(vertices + 2, 3);
  for (int i = 0; i < vertices; ++i) m.vertices.row(i) << u(rng), u(rng), u(rng);
  // Two extra vertices collinear with vertices 0 and 1.
  m.vertices.row(vertices) = 0.5 * (m.vertices.row(0) + m.vertices.row(1));
  m.vertices.row(vertices + 1) = m.vertices.row(0);
  m.faces.resize(faces + 4, 3);
  for (int f = 0; f < faces; ++f) m.faces.row(f) << pick(rng), pick(rng), pick(rng);
  m.faces.row(faces) << 0, 1, vertices;          // collinear
  m.faces.row(faces + 1) << 0, vertices + 1, 1;  // coincident corners (a segment)
  m.faces.row(faces + 2) << 2, 2, 2;             // a point
  m.faces.row(faces + 3) << 3, 4, 3;             // repeated index
  return m;
}

template <typename Action>
void expectInvalid(Action&& action, std::initializer_list<const char*> parts) {
  bool thrown = false;
  try {
    action();
  } catch (const InvalidArgument& e) {
    thrown = true;
    const std::string message = e.what();
    INFO("message: " << message);
    for (const char* part : parts) {
      INFO("expected part: " << part);
      CHECK(message.find(part) != std::string::npos);
    }
  }
  CHECK_MESSAGE(thrown, "no InvalidArgument thrown");
}

/// The faces of m whose bounding boxes meet [lo, hi], by testing every face (ascending).
std::vector<std::int64_t> facesOverlapping(const Mesh& m, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  std::vector<std::int64_t> out;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    bool miss = false;
    for (int c = 0; c < 3; ++c) {
      double mn = 1e300, mx = -1e300;
      for (int k = 0; k < 3; ++k) {
        mn = std::min(mn, m.vertices(m.faces(f, k), c));
        mx = std::max(mx, m.vertices(m.faces(f, k), c));
      }
      miss = miss || mn > hi[c] || mx < lo[c];
    }
    if (!miss) out.push_back(f);
  }
  return out;
}

}  // namespace

TEST_SUITE("measure") {

TEST_CASE("measure: closest point on a triangle, by region, and never NaN on degenerate triangles") {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  ClosestPoint p = closestPointOnTriangle({0.2, 0.2, 0.5}, a, b, c);
  CHECK(p.distance == doctest::Approx(0.5));
  CHECK(p.feature == TriangleFeature::Face);
  p = closestPointOnTriangle({-1, -1, 0}, a, b, c);
  CHECK(p.feature == TriangleFeature::Vertex);
  CHECK(p.local == 0);
  CHECK(p.distance == doctest::Approx(std::sqrt(2.0)));
  p = closestPointOnTriangle({0.5, -2, 0}, a, b, c);
  CHECK(p.feature == TriangleFeature::Edge);
  CHECK(p.local == 0);
  CHECK(p.distance == doctest::Approx(2.0));
  p = closestPointOnTriangle({1, 1, 0}, a, b, c);
  CHECK(p.feature == TriangleFeature::Edge);
  CHECK(p.local == 1);
  CHECK(p.distance == doctest::Approx(std::sqrt(0.5)));
  p = closestPointOnTriangle({-3, 0.5, 0}, a, b, c);
  CHECK(p.feature == TriangleFeature::Edge);
  CHECK(p.local == 2);
  // Degenerate: collinear, coincident corners, a single point, a nearly collinear sliver.
  const Eigen::Vector3d q(0.3, 0.7, -0.2);
  p = closestPointOnTriangle(q, a, b, {2, 0, 0});
  CHECK(p.distance == doctest::Approx(std::hypot(0.7, 0.2)));
  p = closestPointOnTriangle(q, a, a, b);
  CHECK(p.distance == doctest::Approx(std::hypot(0.7, 0.2)));
  p = closestPointOnTriangle(q, b, b, b);
  CHECK(p.distance == doctest::Approx((q - b).norm()));
  CHECK(p.feature == TriangleFeature::Vertex);
  p = closestPointOnTriangle(q, a, b, {0.5, 1e-300, 0});
  CHECK(std::isfinite(p.distance));
  CHECK(p.distance == doctest::Approx(std::hypot(0.7, 0.2)));
}

TEST_CASE("measure: BVH distances equal brute force on random meshes and queries") {
  for (std::uint32_t seed : {1U, 2U, 3U}) {
    const int faces = seed == 1 ? 3 : 700;
    const Mesh m = randomMesh(seed == 1 ? 5 : 300, faces, seed);
    const TriangleBvh tree(m);
    CHECK(tree.faceCount() == static_cast<std::size_t>(m.faces.rows()));
    std::mt19937 rng(seed + 100);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    Points q(400, 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << u(rng), u(rng), u(rng);
    q.row(0) = m.vertices.row(0);  // on the mesh
    const std::vector<ClosestPoint> got = tree.closest(q);
    const Eigen::VectorXd d = tree.distances(q);
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      double best = std::numeric_limits<double>::infinity();
      for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
        const ClosestPoint cp = closestPointOnTriangle(q.row(i).transpose(), m.vertices.row(m.faces(f, 0)).transpose(),
                                                       m.vertices.row(m.faces(f, 1)).transpose(),
                                                       m.vertices.row(m.faces(f, 2)).transpose());
        REQUIRE(std::isfinite(cp.distance));
        best = std::min(best, cp.distance);
      }
      const ClosestPoint& g = got[static_cast<std::size_t>(i)];
      CHECK(std::abs(g.distance - best) <= 1e-12);
      CHECK(d[i] == g.distance);
      CHECK(std::abs((g.point - q.row(i).transpose()).norm() - g.distance) <= 1e-12);
      REQUIRE(g.face >= 0);
      // The reported face really attains the distance.
      const ClosestPoint own = closestPointOnTriangle(q.row(i).transpose(), m.vertices.row(m.faces(g.face, 0)).transpose(),
                                                      m.vertices.row(m.faces(g.face, 1)).transpose(),
                                                      m.vertices.row(m.faces(g.face, 2)).transpose());
      CHECK(own.distance == g.distance);
    }
    CHECK(got[0].distance <= 1e-15);
  }
}

TEST_CASE("measure: a BVH whose two halves are built at once gives brute force's distances and boxes") {
  // 81,920 faces: above the size where the root's two subtrees are built on two threads. Two spheres with
  // jittered vertices (no two triangles alike), queries near and far.
  Mesh m = icosphere(6, 1.0);
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3), u(-1.5, 1.5);
  for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
    for (int c = 0; c < 3; ++c) m.vertices(v, c) += jitter(rng);
  }
  REQUIRE(m.faces.rows() > 65536);
  const TriangleBvh tree(m);
  CHECK(tree.faceCount() == static_cast<std::size_t>(m.faces.rows()));
  CHECK(tree.depth() >= 10);
  Points q(60, 3);
  for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << u(rng), u(rng), u(rng);
  for (Eigen::Index i = 0; i < 20; ++i) q.row(i) = m.vertices.row(i * 97).normalized() * (1.0 + 0.01 * jitter(rng) * 1e3);
  const std::vector<ClosestPoint> got = tree.closest(q);
  std::size_t wrong = 0;
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
      best = std::min(best, closestPointOnTriangle(q.row(i).transpose(), m.vertices.row(m.faces(f, 0)).transpose(),
                                                   m.vertices.row(m.faces(f, 1)).transpose(),
                                                   m.vertices.row(m.faces(f, 2)).transpose())
                                .distance);
    }
    wrong += got[static_cast<std::size_t>(i)].distance == best ? 0 : 1;
  }
  CHECK(wrong == 0);
  // Box queries on both halves and across the split.
  for (const double x0 : {-1.2, -0.1, 0.6}) {
    const Eigen::Vector3d lo(x0, -0.3, -1.2), hi(x0 + 0.5, 0.2, 1.2);
    std::vector<std::int64_t> hits;
    tree.overlapping(lo, hi, hits);
    std::sort(hits.begin(), hits.end());
    const std::vector<std::int64_t> want = facesOverlapping(m, lo, hi);
    CHECK(!want.empty());
    CHECK(hits == want);
  }
}

TEST_CASE("measure: box queries return exactly the faces whose boxes overlap") {
  const Mesh m = randomMesh(200, 500, 7);
  const TriangleBvh tree(m);
  const Eigen::Vector3d lo(-0.3, -0.2, -0.5), hi(0.1, 0.4, 0.0);
  std::vector<std::int64_t> got;
  tree.overlapping(lo, hi, got);
  std::sort(got.begin(), got.end());
  CHECK(got == facesOverlapping(m, lo, hi));
  CHECK(tree.depth() >= 2);
}

TEST_CASE("measure: sampling is deterministic, area-uniform and counts at least N per face") {
  const Mesh m = icosphere(2, 1.0);
  MeasureOptions o;
  o.samplesPerFace = 10;
  o.seed = 42;
  const MeshSamples s1 = sampleMesh(m, o), s2 = sampleMesh(m, o);
  CHECK(s1.points == s2.points);
  CHECK(s1.vertexSamples == static_cast<std::size_t>(m.vertices.rows()));
  const double expected = 10.0 * static_cast<double>(m.faces.rows());
  CHECK(std::abs(static_cast<double>(s1.faceSamples) - expected) <= 4.0 * std::sqrt(expected / 10.0));
  o.seed = 43;
  const MeshSamples s3 = sampleMesh(m, o);
  CHECK((s3.points.rows() != s1.points.rows() || s3.points != s1.points));
  // Every sample lies on its face.
  for (Eigen::Index i = 0; i < s1.points.rows(); i += 7) {
    const std::int64_t f = s1.faces[static_cast<std::size_t>(i)];
    if (f < 0) continue;
    const ClosestPoint cp = closestPointOnTriangle(s1.points.row(i).transpose(), m.vertices.row(m.faces(f, 0)).transpose(),
                                                   m.vertices.row(m.faces(f, 1)).transpose(),
                                                   m.vertices.row(m.faces(f, 2)).transpose());
    CHECK(cp.distance <= 1e-14);
  }
  // Two triangles with areas 3 : 1 receive samples in that ratio; fractional densities work.
  const Mesh two = testing::soup({{{0, 0, 0, 3, 0, 0, 0, 2, 0}}, {{0, 0, 5, 1, 0, 5, 0, 2, 5}}});
  o.samplesPerFace = 2000.5;
  o.includeVertices = false;
  const MeshSamples s = sampleMesh(two, o);
  CHECK(s.vertexSamples == 0);
  std::size_t first = 0;
  for (const auto f : s.faces) first += f == 0 ? 1 : 0;
  CHECK(static_cast<double>(first) / static_cast<double>(s.faceSamples) == doctest::Approx(0.75).epsilon(0.002));
  CHECK(s.faceSamples >= 4000);
  CHECK(s.faceSamples <= 4002);
  // Uniform inside the big triangle: the share below y = 1 is 3/4 of its area.
  std::size_t low = 0;
  for (Eigen::Index i = 0; i < s.points.rows(); ++i) low += s.faces[static_cast<std::size_t>(i)] == 0 && s.points(i, 1) < 1.0;
  CHECK(static_cast<double>(low) / static_cast<double>(first) == doctest::Approx(0.75).epsilon(0.05));
}

TEST_CASE("measure: concentric spheres are the radius difference apart, within the chordal error") {
  const double r1 = 0.9, r2 = 1.0;
  const Mesh inner = icosphere(3, r1), outer = icosphere(3, r2);
  const double h1 = chordalError(inner, r1), h2 = chordalError(outer, r2);
  CHECK(h1 > 0.0);
  MeasureOptions o;
  o.samplesPerFace = 5;
  const DistanceReport r = measureDistance(inner, outer, o);
  const double lo = (r2 - r1) - h2 - 1e-12, hi = (r2 - r1) + h1 + 1e-12;
  for (const SampleStats* s : {&r.forward, &r.backward}) {
    CHECK(s->min >= lo);
    CHECK(s->max <= hi);
    CHECK(s->mean >= lo);
    CHECK(s->mean <= hi);
    CHECK(s->rms >= lo);
    CHECK(s->rms <= hi);
    CHECK(s->p99 <= s->max);
    CHECK(std::abs((s->maxAt - s->maxClosest).norm() - s->max) <= 1e-12);
  }
  CHECK(r.forward.samples > 5u * static_cast<std::size_t>(inner.faces.rows()) * 9 / 10);
  CHECK(r.hausdorff == std::max(r.forward.max, r.backward.max));
  CHECK(r.diagonalB == doctest::Approx(2.0 * std::sqrt(3.0) * r2).epsilon(0.1));
  CHECK(r.forward.max > r.forward.min);
}

TEST_CASE("measure: a mesh against itself is at distance zero") {
  const Mesh m = testing::torus(24, 12, 1.0, 0.3);
  const DistanceReport r = measureDistance(m, m);
  CHECK(r.forward.max <= 1e-12);
  CHECK(r.backward.max <= 1e-12);
  CHECK(r.hausdorff <= 1e-12);
  CHECK(r.forward.samples >= 10u * static_cast<std::size_t>(m.faces.rows()));
}

TEST_CASE("measure: offset statistics of concentric spheres, inward and outward, and the wrong side") {
  const double r = 1.0, delta = 0.1;
  const Mesh surface = icosphere(3, r);
  const Mesh inward = icosphere(3, r - delta), outwardMesh = icosphere(3, r + delta);
  const double hs = chordalError(surface, r);
  MeasureOptions o;
  o.samplesPerFace = 4;
  SUBCASE("inward offset, positive delta") {
    const OffsetReport rep = measureOffset(inward, surface, delta, o);
    const double hi = chordalError(inward, r - delta);
    CHECK(rep.wrongSide == 0);
    CHECK(rep.wrongSideShare == 0.0);
    CHECK(rep.distance.min >= delta - hs - 1e-12);
    CHECK(rep.distance.max <= delta + hi + 1e-12);
    CHECK(rep.deviation.max <= std::max(hs, hi) + 1e-12);
    CHECK(rep.deviation.p99 <= rep.deviation.max);
    CHECK(rep.relativeDeviation.max == doctest::Approx(rep.deviation.max / delta));
    CHECK(rep.relativeDistance.mean == doctest::Approx(rep.distance.mean / delta));
    CHECK(rep.samples == rep.distance.samples);
  }
  SUBCASE("outward offset, negative delta") {
    const OffsetReport rep = measureOffset(outwardMesh, surface, -delta, o);
    CHECK(rep.wrongSide == 0);
    CHECK(rep.deviation.max <= std::max(hs, chordalError(outwardMesh, r + delta)) + 1e-12);
    CHECK(rep.relativeDistance.mean == doctest::Approx(1.0).epsilon(0.05));
  }
  SUBCASE("the side swapped: every sample is on the wrong side") {
    CHECK(measureOffset(inward, surface, -delta, o).wrongSideShare == 1.0);
    CHECK(measureOffset(outwardMesh, surface, delta, o).wrongSideShare == 1.0);
  }
  SUBCASE("a cube surface: samples near its edges and corners are classified by pseudo-normals") {
    // Offset samples of a slightly smaller cube: all inside the unit cube, whose edges and corners
    // are the closest features for many of them.
    Mesh cube;
    cube.vertices.resize(8, 3);
    cube.vertices << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1;
    cube.faces.resize(12, 3);
    cube.faces << 0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 2, 3, 7, 2, 7, 6, 0, 4, 7, 0, 7, 3, 1, 2, 6,
        1, 6, 5;
    Mesh small = cube;
    small.vertices = (cube.vertices.array() * 0.8 + 0.1).matrix();
    Mesh big = cube;
    big.vertices = (cube.vertices.array() * 1.2 - 0.1).matrix();
    CHECK(measureOffset(small, cube, 0.1, o).wrongSide == 0);
    CHECK(measureOffset(big, cube, -0.1, o).wrongSide == 0);
    CHECK(measureOffset(big, cube, 0.1, o).wrongSideShare == 1.0);
  }
}

TEST_CASE("measure: offset components on the offset are told apart from a spurious sheet") {
  const double r = 1.0, delta = 0.1;
  const Mesh surface = icosphere(3, r);
  // The inward offset sphere, two small pieces of it (a cap-sized sphere centred on the offset sphere's
  // radius) and a spurious sphere near the centre, far from distance δ of the surface.
  Mesh o = icosphere(3, r - delta);
  for (const Mesh& extra : {icosphere(1, 0.01, Eigen::RowVector3d(0.0, 0.0, -(r - delta))),
                            icosphere(2, 0.05, Eigen::RowVector3d(0.0, 0.1, 0.0))}) {
    const auto base = static_cast<Index>(o.vertices.rows());
    Mesh merged;
    merged.vertices.resize(o.vertices.rows() + extra.vertices.rows(), 3);
    merged.vertices << o.vertices, extra.vertices;
    merged.faces.resize(o.faces.rows() + extra.faces.rows(), 3);
    merged.faces << o.faces, (extra.faces.array() + base).matrix();
    o = std::move(merged);
  }
  std::size_t count = 0;
  const std::vector<Index> labels = faceComponents(o, &count);
  CHECK(count == 3);
  CHECK(labels.size() == static_cast<std::size_t>(o.faces.rows()));
  MeasureOptions opts;
  opts.samplesPerFace = 2;
  const OffsetReport rep = measureOffset(o, surface, delta, opts);
  REQUIRE(rep.components.size() == 3);
  CHECK(rep.offOffsetComponents == 1);
  CHECK(rep.components[0].faces == static_cast<std::size_t>(icosphere(3, 1.0).faces.rows()));  // largest first
  CHECK_FALSE(rep.components[0].offOffset);
  CHECK(rep.components[0].meanDistance == doctest::Approx(delta).epsilon(0.05));
  std::size_t spurious = 0;
  for (const auto& c : rep.components) {
    if (c.offOffset) {
      ++spurious;
      CHECK(c.meanDistance > 0.8);  // the sphere near the centre is about 0.9 from the surface
    }
  }
  CHECK(spurious == 1);
}

TEST_CASE("measure: invalid meshes and options are errors naming the source and element") {
  Mesh m = icosphere(0, 1.0);
  SUBCASE("no faces") {
    Mesh empty;
    empty.vertices = m.vertices;
    expectInvalid([&] { validateMesh(empty, "a.ply"); }, {"a.ply", "no faces"});
    expectInvalid([&] { measureDistance(empty, m); }, {"first mesh", "no faces"});
    expectInvalid([&] { checkMesh(empty); }, {"no faces"});
    expectInvalid([&] { TriangleBvh tree(empty); }, {"no faces"});
  }
  SUBCASE("an index out of range, a negative index") {
    m.faces(12, 1) = 99;
    expectInvalid([&] { validateMesh(m, "b.obj"); }, {"b.obj: face 12: index 99 out of range (mesh has 12 vertices)"});
    expectInvalid([&] { measureDistance(icosphere(0, 2.0), m); }, {"second mesh", "face 12"});
    m.faces(12, 1) = -1;
    expectInvalid([&] { validateMesh(m, "b.obj"); }, {"face 12: index -1 out of range"});
  }
  SUBCASE("NaN and infinite vertices") {
    m.vertices(7, 1) = std::nan("");
    expectInvalid([&] { validateMesh(m, "c.stl"); }, {"c.stl: vertex 7: coordinate y is NaN"});
    expectInvalid([&] { measureOffset(m, icosphere(0, 2.0), 0.1); }, {"offset mesh", "vertex 7"});
    m.vertices(7, 1) = std::numeric_limits<double>::infinity();
    expectInvalid([&] { checkMesh(m); }, {"vertex 7", "infinite"});
  }
  SUBCASE("degenerate triangles are counted, not rejected") {
    Mesh d = m;
    d.faces.conservativeResize(m.faces.rows() + 2, 3);
    d.faces.row(m.faces.rows()) << 1, 1, 2;
    d.vertices.conservativeResize(m.vertices.rows() + 1, 3);
    d.vertices.row(m.vertices.rows()) = 0.5 * (m.vertices.row(0) + m.vertices.row(1));
    d.faces.row(m.faces.rows() + 1) << 0, 1, static_cast<std::int32_t>(m.vertices.rows());
    const MeshValidation v = validateMesh(d);
    CHECK(v.repeatedIndexFaces == 1);
    CHECK(v.zeroAreaFaces == 1);
    CHECK(v.degenerateFaces() == 2);
    CHECK(v.firstDegenerateFace == m.faces.rows());
    CHECK(validateMesh(m).degenerateFaces() == 0);
    const DistanceReport r = measureDistance(d, m);
    CHECK(std::isfinite(r.hausdorff));
    CHECK(r.hausdorff <= 1e-12);
    CHECK(checkMesh(d).validation.degenerateFaces() == 2);
  }
  SUBCASE("bad options") {
    MeasureOptions o;
    o.samplesPerFace = 0;
    expectInvalid([&] { measureDistance(m, m, o); }, {"samples per face", "positive"});
    expectInvalid([&] { sampleMesh(m, o); }, {"samples per face"});
    o.samplesPerFace = std::nan("");
    expectInvalid([&] { measureDistance(m, m, o); }, {"samples per face"});
    expectInvalid([&] { measureOffset(m, m, 0.0); }, {"delta"});
    expectInvalid([&] { measureOffset(m, m, std::nan("")); }, {"delta"});
  }
}

}  // TEST_SUITE
