// The self-check of a fit's meshes on generated spheres with planted spurious components: a zero-level
// sphere no input point lands on, an offset sphere at the wrong distance from the zero level, correct sets
// without issues, the removal of small components (area bookkeeping, vertex compaction), and bad input.
#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/self_check.hpp"
#include "core/mesh_shapes.hpp"
#include "measure/measure_shapes.hpp"
#include "shapes.hpp"

namespace {

using namespace duplexfit;
using testing::icosphere;
const auto merged = testing::concatenate;  // the union of two meshes

/// Points on the unit sphere (the input cloud of the zero level).
Points unitSpherePoints(int n = 2000) { return testing::fibonacciSphere(n, 1.0); }

}  // namespace

TEST_SUITE("surfaces") {

TEST_CASE("self-check: a correct zero level and offsets on both sides have no issues") {
  const std::vector<Mesh> meshes = {icosphere(4, 1.0), icosphere(4, 0.8), icosphere(4, 1.1)};
  const SelfCheckReport r = selfCheck(meshes, {0.0, 0.2, -0.1}, unitSpherePoints());
  CHECK(r.ok());
  CHECK(r.issues.empty());
  CHECK(r.pointsChecked);
  CHECK(r.pointTolerance > 0.0);
  CHECK(r.pointTolerance < 0.2);  // 2 mean edges of a level-4 icosphere of radius 1 (about 0.08 each)
  REQUIRE(r.surfaces.size() == 3);
  for (const SurfaceSelfCheck& s : r.surfaces) {
    CHECK(s.components == 1);
    CHECK(s.issues == 0);
    CHECK(s.dropped.components == 0);
  }
  CHECK(r.surfaces[1].iso == 0.2);
  CHECK(r.surfaces[0].area == doctest::Approx(surfaceArea(meshes[0])));
  CHECK(r.seconds >= 0.0);
}

TEST_CASE("self-check: the thinnest wall between an offset and the zero level, and where it is") {
  // The unit icosphere and an inward offset of radius 0.8: every offset vertex lies 0.2 from the zero mesh
  // (within the flat faces' sag, about 0.003 at level 4); outward at 1.1: 0.1.
  std::vector<Mesh> meshes = {icosphere(4, 1.0), icosphere(4, 0.8), icosphere(4, 1.1)};
  SelfCheckOptions all;
  all.offsetVertexSamples = 0;  // every vertex measured
  const SelfCheckReport r = selfCheck(meshes, {0.0, 0.2, -0.1}, unitSpherePoints(), all);
  REQUIRE(r.surfaces.size() == 3);
  CHECK(std::isnan(r.surfaces[0].thinnestWall));  // the zero level has none
  CHECK(r.surfaces[1].thinnestWall == doctest::Approx(0.2).epsilon(0.02));
  CHECK(r.surfaces[2].thinnestWall == doctest::Approx(0.1).epsilon(0.05));
  CHECK(r.surfaces[1].thinnestWallAt.norm() == doctest::Approx(0.8));
  // One vertex of the inward offset pulled out to radius 0.95 (a fin towards the surface): the wall there
  // is 0.05 or less, the check names that vertex, and the component as a whole is still on the offset.
  const Eigen::Index v = 17;
  meshes[1].vertices.row(v) *= 0.95 / 0.8;
  const SelfCheckReport fin = selfCheck(meshes, {0.0, 0.2, -0.1}, unitSpherePoints(), all);
  CHECK(fin.ok());
  CHECK(fin.surfaces[1].thinnestWall < 0.051);
  CHECK(fin.surfaces[1].thinnestWall > 0.04);
  CHECK((fin.surfaces[1].thinnestWallAt - meshes[1].vertices.row(v).transpose()).norm() == 0.0);
  CHECK(fin.surfaces[2].thinnestWall == doctest::Approx(r.surfaces[2].thinnestWall));
}

TEST_CASE("self-check: a planted zero-level sphere without input points is exactly one issue") {
  const Mesh surface = icosphere(4, 1.0);
  const Mesh planted = icosphere(2, 0.1, Eigen::RowVector3d(3.0, 0.0, 0.0));
  const std::vector<Mesh> meshes = {merged(surface, planted)};
  const SelfCheckReport r = selfCheck(meshes, {0.0}, unitSpherePoints());
  REQUIRE(r.issues.size() == 1);
  const ComponentIssue& i = r.issues[0];
  CHECK(i.why == ComponentIssue::Why::NoInputPoints);
  CHECK(std::string(componentIssueName(i.why)) == "no_input_points");
  CHECK(i.surface == 0);
  CHECK(i.component == 1);  // labels follow the first face: the unit sphere comes first
  CHECK(i.faces == static_cast<std::size_t>(planted.faces.rows()));
  CHECK(i.vertices == static_cast<std::size_t>(planted.vertices.rows()));
  CHECK(i.area == doctest::Approx(surfaceArea(planted)));
  CHECK(i.areaFraction == doctest::Approx(surfaceArea(planted) / surfaceArea(meshes[0])));
  CHECK(i.box.min().x() == doctest::Approx(2.9).epsilon(1e-6));
  CHECK(i.box.max().x() == doctest::Approx(3.1).epsilon(1e-6));
  CHECK(i.box.max().y() == doctest::Approx(0.1).epsilon(1e-2));
  CHECK(i.nearestInputPoint == doctest::Approx(1.9).epsilon(2e-3));  // vertex (2.9, 0, 0) to about (1, 0, 0)
  CHECK(std::isnan(i.meanDistance));
  CHECK(r.surfaces[0].components == 2);
  CHECK(r.surfaces[0].issues == 1);

  // With input points on the planted sphere too, nothing is flagged; without points, nothing is tested.
  Points both(2000 + 50, 3);
  both << unitSpherePoints(), testing::fibonacciSphere(50, 0.1);
  both.bottomRows(50).col(0).array() += 3.0;
  CHECK(selfCheck(meshes, {0.0}, both).ok());
  const SelfCheckReport none = selfCheck(meshes, {0.0}, Points(0, 3));
  CHECK(none.ok());
  CHECK_FALSE(none.pointsChecked);
}

TEST_CASE("self-check: a component within the tolerance of points nearer to another one carries them") {
  // A tiny sphere just inside the unit sphere: the points near it are closer to the unit sphere, yet within
  // the tolerance of the tiny one (found in the second round, on the components not yet credited).
  const Mesh surface = icosphere(4, 1.0);
  const Mesh tiny = icosphere(1, 0.01, Eigen::RowVector3d(0.97, 0.0, 0.0));
  const std::vector<Mesh> meshes = {merged(surface, tiny)};
  Points points(2001, 3);
  points << unitSpherePoints(), Eigen::RowVector3d(1.0, 0.0, 0.0);
  SelfCheckOptions o;
  o.pointTolerance = 0.05;
  CHECK(selfCheck(meshes, {0.0}, points, o).ok());
  o.pointTolerance = 0.005;
  const SelfCheckReport r = selfCheck(meshes, {0.0}, points, o);
  REQUIRE(r.issues.size() == 1);
  CHECK(r.issues[0].component == 1);
  CHECK(r.issues[0].nearestInputPoint == doctest::Approx(0.02).epsilon(1e-6));
}

TEST_CASE("self-check: candidateEdges lists the components without points within fewer edges, issues or not") {
  // The tiny sphere of the case above with its one point at 0.03 from it (the unit sphere's own points are
  // farther): within the check's two mean edges (about 0.16), beyond one edge's worth of 0.02.
  const Mesh surface = icosphere(4, 1.0);
  const Mesh planted = icosphere(2, 0.1, Eigen::RowVector3d(3.0, 0.0, 0.0));
  const std::vector<Mesh> meshes = {merged(surface, planted)};
  Points points(2001, 3);
  points << unitSpherePoints(), Eigen::RowVector3d(3.13, 0.0, 0.0);
  SelfCheckOptions o;
  const SelfCheckReport plain = selfCheck(meshes, {0.0}, points, o);
  CHECK(plain.ok());
  CHECK(plain.emptyComponents.empty());  // not asked
  // One edge of the unit sphere's mesh is about 0.08, its mean with the small sphere's about the same: a
  // quarter of an edge keeps the point (0.03 off) out.
  o.candidateEdges = 0.25;
  const SelfCheckReport loose = selfCheck(meshes, {0.0}, points, o);
  CHECK(loose.ok());  // the same issues: none
  REQUIRE(loose.emptyComponents.size() == 1);
  const EmptyComponent& e = loose.emptyComponents[0];
  CHECK(e.component == 1);
  CHECK(e.faces == static_cast<std::size_t>(planted.faces.rows()));
  CHECK(e.faceList.size() == e.faces);
  CHECK(e.vertexList.size() == static_cast<std::size_t>(planted.vertices.rows()));
  CHECK(e.faceList.front() == surface.faces.rows());  // the planted sphere's faces come second
  CHECK(e.nearestInputPoint == doctest::Approx(0.03).epsilon(1e-6));
  // The free function answers alike; a bad tolerance is an error.
  const std::vector<EmptyComponent> direct = emptyZeroLevelComponents(meshes[0], points, 0.25);
  REQUIRE(direct.size() == 1);
  CHECK(direct[0].faceList == e.faceList);
  CHECK_THROWS_AS(emptyZeroLevelComponents(meshes[0], points, 0.0), InvalidArgument);
  // candidatesFirst: with candidates the offsets wait (a planted offset sphere at the wrong distance is not
  // reported yet); without any they are checked as usual.
  const Mesh offset = merged(icosphere(4, 0.8), icosphere(2, 0.05, Eigen::RowVector3d(-3.0, 0.0, 0.0)));
  const std::vector<Mesh> withOffset = {meshes[0], offset};
  o.candidatesFirst = true;
  const SelfCheckReport first = selfCheck(withOffset, {0.0, 0.2}, points, o);
  CHECK_FALSE(first.offsetsChecked);
  CHECK(first.emptyComponents.size() == 1);
  CHECK(first.ok());
  o.candidateEdges = 0.0;  // nothing listed: the offsets are checked in the same call
  const SelfCheckReport whole = selfCheck(withOffset, {0.0, 0.2}, points, o);
  CHECK(whole.offsetsChecked);
  REQUIRE(whole.issues.size() == 1);
  CHECK(whole.issues[0].why == ComponentIssue::Why::OffOffset);
  o.candidateEdges = -1.0;
  CHECK_THROWS_AS(selfCheck(meshes, {0.0}, points, o), InvalidArgument);
}

TEST_CASE("self-check: the point tolerance decides whether a point lands on a component") {
  const std::vector<Mesh> meshes = {icosphere(3, 1.0)};
  Points far = unitSpherePoints(500) * 1.05;  // 0.05 outside (plus the chordal gap inside the facets)
  SelfCheckOptions o;
  o.pointTolerance = 0.02;
  const SelfCheckReport strictTol = selfCheck(meshes, {0.0}, far, o);
  REQUIRE(strictTol.issues.size() == 1);
  CHECK(strictTol.issues[0].nearestInputPoint == doctest::Approx(0.05).epsilon(0.2));
  CHECK(strictTol.pointTolerance == 0.02);
  o.pointTolerance = 0.1;
  CHECK(selfCheck(meshes, {0.0}, far, o).ok());
}

TEST_CASE("self-check: a planted offset sphere at the wrong distance is exactly one issue") {
  const double delta = 0.2;
  const Mesh zero = icosphere(4, 1.0);
  const Mesh inner = icosphere(4, 1.0 - delta);
  const Mesh planted = icosphere(2, 0.1, Eigen::RowVector3d(0.2, 0.0, 0.0));  // about 0.78 from the surface
  const std::vector<Mesh> meshes = {zero, merged(inner, planted)};
  const SelfCheckReport r = selfCheck(meshes, {0.0, delta}, unitSpherePoints());
  REQUIRE(r.issues.size() == 1);
  const ComponentIssue& i = r.issues[0];
  CHECK(i.why == ComponentIssue::Why::OffOffset);
  CHECK(std::string(componentIssueName(i.why)) == "off_offset");
  CHECK(i.surface == 1);
  CHECK(i.iso == delta);
  CHECK(i.component == 1);
  CHECK(i.faces == static_cast<std::size_t>(planted.faces.rows()));
  CHECK(i.meanDistance == doctest::Approx(1.0 - (0.2 + 0.01 / 0.6)).epsilon(0.01));  // 1 − mean |vertex|
  CHECK(i.meanDeviation == doctest::Approx(i.meanDistance - delta));
  CHECK(std::isnan(i.nearestInputPoint));
  CHECK(i.box.min().x() == doctest::Approx(0.1).epsilon(1e-6));
  CHECK(r.surfaces[1].components == 2);
  CHECK(r.surfaces[1].issues == 1);
  CHECK(r.surfaces[0].issues == 0);

  // Measuring only every k-th vertex (about 10 a component) tells them apart just as well.
  SelfCheckOptions few;
  few.offsetVertexSamples = 10;
  const SelfCheckReport sampled = selfCheck(meshes, {0.0, delta}, unitSpherePoints(), few);
  REQUIRE(sampled.issues.size() == 1);
  CHECK(sampled.issues[0].component == 1);
  CHECK(sampled.issues[0].meanDistance == doctest::Approx(i.meanDistance).epsilon(0.1));
  CHECK(sampled.issues[0].vertices == i.vertices);

  // A small sphere at about |δ| from the surface is a legitimate piece of the offset (a separate component
  // even where it crosses the inner sphere: components are connected by shared vertices).
  const Mesh onOffset = icosphere(2, 0.05, Eigen::RowVector3d(0.0, 0.0, 0.8));
  CHECK(selfCheck({zero, merged(inner, onOffset)}, {0.0, delta}, unitSpherePoints()).ok());
  // Without a zero-level mesh no offset component can be placed: each one is an issue.
  const SelfCheckReport noZero = selfCheck({Mesh{}, inner}, {0.0, delta}, unitSpherePoints());
  REQUIRE(noZero.issues.size() == 1);
  CHECK(noZero.issues[0].why == ComponentIssue::Why::OffOffset);
  CHECK(std::isinf(noZero.issues[0].meanDistance));
}

TEST_CASE("dropSmallComponents: removes the small component, compacts the vertices, keeps the area sum") {
  const Mesh big = icosphere(3, 1.0);
  const Mesh small = icosphere(1, 0.1, Eigen::RowVector3d(3.0, 0.0, 0.0));
  const Mesh both = merged(small, big);  // the small one first, so vertex and face indices shift
  const double total = surfaceArea(both);
  const DropResult result = dropSmallComponents(both, 0.05);
  const DroppedComponents& d = result.dropped;
  const Mesh& kept = result.mesh;
  CHECK(d.components == 1);
  CHECK(d.faces == static_cast<std::size_t>(small.faces.rows()));
  CHECK(d.vertices == static_cast<std::size_t>(small.vertices.rows()));
  CHECK(d.area == doctest::Approx(surfaceArea(small)));
  CHECK(d.areaFraction == doctest::Approx(surfaceArea(small) / total));
  CHECK(surfaceArea(kept) + d.area == doctest::Approx(total));
  CHECK(kept.vertices.rows() == big.vertices.rows());
  CHECK(kept.faces.rows() == big.faces.rows());
  CHECK(kept.vertices.isApprox(big.vertices));  // the remaining vertices keep their order
  CHECK((kept.faces.array() == big.faces.array()).all());
  const MeshTopology t = analyzeTopology(kept);
  CHECK(t.components == 1);
  CHECK(t.watertight());

  // 0 drops nothing; a fraction above every component's share still keeps the largest.
  const DropResult noneResult = dropSmallComponents(both, 0.0);
  const DroppedComponents& none = noneResult.dropped;
  CHECK(noneResult.mesh.faces.rows() == both.faces.rows());
  CHECK(none.components == 0);
  const Mesh twins = merged(icosphere(2, 1.0), icosphere(2, 1.0, Eigen::RowVector3d(5.0, 0.0, 0.0)));
  const DropResult halfResult = dropSmallComponents(twins, 0.9);
  const DroppedComponents& half = halfResult.dropped;
  CHECK(analyzeTopology(halfResult.mesh).components == 1);
  CHECK(half.components == 1);
  CHECK(half.areaFraction == doctest::Approx(0.5));
  CHECK_THROWS_AS(dropSmallComponents(both, 1.0), InvalidArgument);
  CHECK_THROWS_AS(dropSmallComponents(both, -0.1), InvalidArgument);
  CHECK_THROWS_AS(dropSmallComponents(both, std::nan("")), InvalidArgument);
}

TEST_CASE("cleanAndSelfCheck: a dropped spurious component is reported as dropped, not as an issue") {
  std::vector<Mesh> meshes = {merged(icosphere(4, 1.0), icosphere(2, 0.1, Eigen::RowVector3d(3.0, 0.0, 0.0))),
                              merged(icosphere(4, 0.8), icosphere(2, 0.1))};
  const std::vector<Mesh> original = meshes;
  SelfCheckOptions o;
  CHECK(cleanAndSelfCheck(meshes, {0.0, 0.2}, unitSpherePoints(), o).issues.size() == 2);  // 0: drops nothing
  CHECK(meshes[0].faces.rows() == original[0].faces.rows());
  o.minAreaFraction = 0.05;  // the planted spheres are 1% and 1.5% of their meshes' areas
  const SelfCheckReport r = cleanAndSelfCheck(meshes, {0.0, 0.2}, unitSpherePoints(), o);
  CHECK(r.ok());
  CHECK(r.minAreaFraction == 0.05);
  REQUIRE(r.surfaces.size() == 2);
  for (std::size_t i = 0; i < 2; ++i) {
    CHECK(r.surfaces[i].components == 1);
    CHECK(r.surfaces[i].dropped.components == 1);
    CHECK(r.surfaces[i].dropped.faces == 320);
    CHECK(r.surfaces[i].area + r.surfaces[i].dropped.area == doctest::Approx(surfaceArea(original[i])));
    CHECK(analyzeTopology(meshes[i]).components == 1);
  }
}

TEST_CASE("dropSmallComponents of a fit's meshes: the zero level at minAreaFraction, offsets at the larger fraction") {
  // The small sphere is 1% of each mesh's area: only the offsets' 0.02 drops it.
  std::vector<Mesh> meshes = {merged(icosphere(4, 1.0), icosphere(2, 0.1, Eigen::RowVector3d(3.0, 0.0, 0.0))),
                              merged(icosphere(4, 1.0), icosphere(2, 0.1, Eigen::RowVector3d(3.0, 0.0, 0.0)))};
  SelfCheckOptions o;
  o.minAreaFraction = 0.005;
  o.minOffsetAreaFraction = 0.02;
  CHECK(dropFraction(o, 0) == 0.005);
  CHECK(dropFraction(o, 1) == 0.02);
  CHECK(dropFraction(o, 7) == 0.02);
  const std::vector<DroppedComponents> d = dropSmallComponents(meshes, o);
  REQUIRE(d.size() == 2);
  CHECK(d[0].components == 0);
  CHECK(d[0].minAreaFraction == 0.005);
  CHECK(analyzeTopology(meshes[0]).components == 2);
  CHECK(d[1].components == 1);
  CHECK(d[1].minAreaFraction == 0.02);
  CHECK(analyzeTopology(meshes[1]).components == 1);
  o.minOffsetAreaFraction = 1.0;
  CHECK_THROWS_AS(dropSmallComponents(meshes, o), InvalidArgument);
}

TEST_CASE("self-check: bad input is a clear error") {
  const std::vector<Mesh> one = {icosphere(1, 1.0)};
  const Points p = unitSpherePoints(100);
  CHECK_THROWS_AS(selfCheck(one, {0.0, 0.1}, p), InvalidArgument);
  CHECK_THROWS_AS(selfCheck({}, {}, p), InvalidArgument);
  CHECK_THROWS_AS(selfCheck(one, {0.1}, p), InvalidArgument);
  CHECK_THROWS_AS(selfCheck({icosphere(1, 1.0), icosphere(1, 0.9)}, {0.0, 0.0}, p), InvalidArgument);
  SelfCheckOptions o;
  o.pointTolerance = -1.0;
  CHECK_THROWS_AS(selfCheck(one, {0.0}, p, o), InvalidArgument);
  o = {};
  o.minAreaFraction = 2.0;
  CHECK_THROWS_AS(selfCheck(one, {0.0}, p, o), InvalidArgument);
  Mesh bad = icosphere(1, 1.0);
  bad.faces(0, 0) = 10000;
  CHECK_THROWS_AS(selfCheck({bad}, {0.0}, p), InvalidArgument);
}

}  // TEST_SUITE
