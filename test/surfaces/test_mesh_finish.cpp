// The pipelines' finishing of level-set meshes: cleaning a marching-tetrahedra sphere (watertight, no
// float32-degenerate triangle, also after an STL round trip), the default cell without the δ term and the
// deviation bound on a radial field whose level sets are spheres, and simplification under a budget
// (skipped with a message in a build without meshoptimizer).
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "duplexfit/pipeline.hpp"
#include "duplexfit/polygonize.hpp"
#include "duplexfit/surfaces.hpp"
#include "data.hpp"
#include "skip.hpp"
#include "surfaces/collapse.hpp"
#include "temp_dir.hpp"
#include "test_device.hpp"

namespace {

using namespace duplexfit;

/// f = r − |x − c| sampled on the grid, and its mesh.
Mesh sphereMesh(const Eigen::Vector3d& c, double r, double cell, double iso = 0.0) {
  const GridSpec grid = GridSpec::fromCellSize(
      Eigen::AlignedBox3d(c - Eigen::Vector3d::Constant(r + 4 * cell), c + Eigen::Vector3d::Constant(r + 4 * cell)),
      cell);
  const FieldSampler sampler = [c, r](const Points& q, Eigen::VectorXd& v) {
    v.resize(q.rows());
    for (Eigen::Index i = 0; i < q.rows(); ++i) v[i] = r - (q.row(i).transpose() - c).norm();
  };
  return polygonize(sampler, grid, {iso}).meshes[0];
}

/// max ||v − c| − r| over the vertices.
double radialError(const Mesh& m, const Eigen::Vector3d& c, double r) {
  double e = 0.0;
  for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
    e = std::max(e, std::abs((m.vertices.row(v).transpose() - c).norm() - r));
  }
  return e;
}

/// Moves the far end of the mesh's shortest edge to within 1e-10 of its length from the near end: in
/// float32 the two are then one point (at coordinates of a few hundred).
Mesh withCoincidingPair(Mesh m) {
  double best = 1e300;
  std::int32_t a = -1, b = -1;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const std::int32_t p = m.faces(f, k), q = m.faces(f, (k + 1) % 3);
      const double len = (m.vertices.row(p) - m.vertices.row(q)).norm();
      if (len < best) {
        best = len;
        a = p;
        b = q;
      }
    }
  }
  m.vertices.row(b) = m.vertices.row(a) + 1e-10 * (m.vertices.row(b) - m.vertices.row(a));
  return m;
}

/// A field of one Wendland bump, f(x) = −0.5 + φ(|x|/2): radial, so its level sets are spheres (f = 0 at
/// |x| ≈ 0.627), |∇f| ≈ 1 there, like a distance.
ImplicitField radialField(double finestSigma = 2.0) {
  FieldLevel level;
  level.sigma = finestSigma;
  level.centres = Points::Zero(1, 3);
  level.weights = Eigen::VectorXd::Ones(1);
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d::Constant(-0.7), Eigen::Vector3d::Constant(0.7));
  return ImplicitField(Normalization{}, -0.5, {level}, {}, bounds);
}

}  // namespace

TEST_SUITE("surfaces") {

TEST_CASE("cleaning keeps a marching-tetrahedra sphere watertight and removes every float32-degenerate triangle") {
  // Far from the origin (float32 spacing 3e-5) and with grid nodes exactly on the sphere, so that many
  // crossings sit next to the nodes.
  const Eigen::Vector3d c(300.0, -200.0, 100.0);
  const double cell = 0.05, r = 0.5;
  const Mesh raw = withCoincidingPair(sphereMesh(c, r, cell));
  const TriangleQuality before = triangleQuality(raw);
  REQUIRE(before.float32DegenerateFaces >= 2);
  MESSAGE("raw: " << before.faces << " faces, " << before.below1 << " / " << before.below5 << " / " << before.below10
                   << " below 1/5/10 deg, min angle " << before.minAngle << ", shortest edge " << before.shortestEdge);
  const MeshTopology rawTopology = analyzeTopology(raw);
  REQUIRE(rawTopology.watertight());

  CleanOptions options;
  options.collapseLength = 0.1 * cell;
  const CleanResult cleaned = cleanMesh(raw, options);
  const CleanReport& rep = cleaned.report;
  CHECK(rep.collapses > 0);
  CHECK(rep.facesAfter < rep.facesBefore);
  CHECK(rep.float32DegenerateBefore == before.float32DegenerateFaces);
  CHECK(rep.float32DegenerateAfter == 0);
  CHECK(rep.sliversAfter <= rep.sliversBefore);
  CHECK(rep.minAngleAfter > rep.minAngleBefore);
  CHECK(rep.lockedVertices == 0);
  const MeshTopology t = analyzeTopology(cleaned.mesh);
  CHECK(t.watertight());
  CHECK(t.manifold());
  CHECK(t.oriented());
  CHECK(t.components == 1);
  CHECK(t.eulerCharacteristic == 2);
  const MeshCheck check = checkMesh(cleaned.mesh);
  CHECK(check.quality.float32DegenerateFaces == 0);
  CHECK(check.selfIntersections == 0);
  CHECK(check.valid());
  // The vertices stay on the sphere as well as the marching tetrahedra put them.
  CHECK(radialError(cleaned.mesh, c, r) <= radialError(raw, c, r) + 1e-3 * cell);

  // Written in float32 and read back (the STL reader welds identical corners): still valid.
  const testing::TempDir dir;
  writeMesh(dir.file("clean.stl"), cleaned.mesh);
  const MeshCheck stl = checkMesh(readMesh(dir.file("clean.stl")));
  CHECK(stl.quality.float32DegenerateFaces == 0);
  CHECK(stl.valid());
  writeMesh(dir.file("raw.stl"), raw);
  CHECK_FALSE(checkMesh(readMesh(dir.file("raw.stl"))).valid());
}

TEST_CASE("cleaning does not fold a sharp tip through itself") {
  // A patch of a raw offset mesh (test/data/README.md) where collapsing a short edge at its midpoint makes
  // a surviving face cross others around it although none turns more than 60 degrees; the cleaning then
  // takes another position or leaves the edge.
  const Mesh raw = readMesh(testing::repoTestDataDir() + "/wheel29k_offset_fold.ply");
  REQUIRE(raw.faces.rows() == 431);
  REQUIRE(checkMesh(raw).selfIntersections == 0);
  for (const double length : {5e-4, 7.8117e-4, 1e-3, 2e-3}) {
    CAPTURE(length);
    CleanOptions options;
    options.collapseLength = length;
    const CleanResult cleaned = cleanMesh(raw, options);
    CHECK(cleaned.report.collapses > 50);
    const MeshCheck c = checkMesh(cleaned.mesh);
    CHECK(c.selfIntersections == 0);
    CHECK(c.topology.eulerCharacteristic == analyzeTopology(raw).eulerCharacteristic);
    CHECK(c.boundaryLoops == checkMesh(raw).boundaryLoops);
  }
}

TEST_CASE("cleaning does not flip a cap through the triangles around it") {
  // A patch of a raw offset mesh (test/data/README.md) where, after the collapses, flipping the long edge of
  // a cap gives two triangles within 20 degrees of each other and of the pair they replace that cross a
  // triangle around them; the cleaning leaves that cap as it is.
  const Mesh raw = readMesh(testing::repoTestDataDir() + "/wheel29k_offset_flip.ply");
  REQUIRE(raw.faces.rows() == 306);
  REQUIRE(checkMesh(raw).selfIntersections == 0);
  CleanOptions options;
  options.collapseLength = 7.8117e-4;
  const CleanResult cleaned = cleanMesh(raw, options);
  CHECK(cleaned.report.collapses > 50);
  CHECK(cleaned.report.flips > 0);
  CHECK(cleaned.report.refusedFlips > 0);
  const MeshCheck c = checkMesh(cleaned.mesh);
  CHECK(c.selfIntersections == 0);
  CHECK(c.topology.eulerCharacteristic == analyzeTopology(raw).eulerCharacteristic);
  CHECK(c.boundaryLoops == checkMesh(raw).boundaryLoops);
}

TEST_CASE("a pipeline surface is sound only closed, manifold, oriented and without pairs left by the projection") {
  // `fit --strict` exits with status 4 unless every mesh it writes is sound.
  Mesh tet;
  tet.vertices.resize(4, 3);
  tet.vertices << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  tet.faces.resize(4, 3);
  tet.faces << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  PipelineSurface s;
  s.mesh = tet;
  s.topology = analyzeTopology(tet);
  CHECK(s.sound());
  s.finish.project.selfIntersectionsChecked = true;
  CHECK(s.sound());
  s.finish.project.selfIntersectionsLeft = 2;
  CHECK_FALSE(s.sound());
  s.finish.project.selfIntersectionsChecked = false;  // not checked: nothing known to be left
  CHECK(s.sound());
  // What `check` refuses beside the topology: a triangle degenerate in float32, slivers beyond the share.
  s.quality = triangleQuality(tet);
  CHECK(s.sound());
  s.quality.float32DegenerateFaces = 1;
  CHECK_FALSE(s.sound());
  s.quality.float32DegenerateFaces = 0;
  s.quality.faces = 1000;
  s.quality.slivers = 1;  // 0.1%: allowed
  CHECK(s.sound());
  s.quality.slivers = 2;
  CHECK_FALSE(s.sound());
  s.quality = TriangleQuality{};
  s.finish.project = ProjectReport{};
  Mesh open = tet;
  open.faces.conservativeResize(3, 3);
  s.topology = analyzeTopology(open);
  CHECK_FALSE(s.sound());
  Mesh flipped = tet;
  flipped.faces.row(3) << 1, 3, 2;
  s.topology = analyzeTopology(flipped);
  CHECK_FALSE(s.sound());
}

TEST_CASE("cleaning: an open mesh keeps its boundary; bad options are rejected") {
  Mesh m = sphereMesh(Eigen::Vector3d::Zero(), 0.5, 0.05);
  // Cut the mesh open: drop every face with a vertex above z = 0.3.
  std::vector<Eigen::Index> kept;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    bool low = true;
    for (int k = 0; k < 3; ++k) low = low && m.vertices(m.faces(f, k), 2) < 0.3;
    if (low) kept.push_back(f);
  }
  Mesh open = m;
  open.faces.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (std::size_t i = 0; i < kept.size(); ++i) open.faces.row(static_cast<Eigen::Index>(i)) = m.faces.row(kept[i]);
  const MeshTopology before = analyzeTopology(open);
  CleanOptions o;
  o.collapseLength = 0.005;
  const CleanResult r = cleanMesh(open, o);
  CHECK(r.report.lockedVertices > 0);
  const MeshTopology after = analyzeTopology(r.mesh);
  CHECK(after.boundaryEdges == before.boundaryEdges);
  CHECK(after.nonManifoldEdges == 0);
  CHECK(after.manifold());
  CHECK(after.oriented());
  CHECK(after.eulerCharacteristic == before.eulerCharacteristic);
  o.collapseLength = -1.0;
  CHECK_THROWS_AS(cleanMesh(open, o), InvalidArgument);
}

TEST_CASE("the default cell does not depend on the offsets, and the meshes stay within 0.1% of the box") {
  const ImplicitField field = radialField(0.02);  // σ_M/2 = 0.01, between side/512 and side/128
  const double cell = surfaceGrid(field, {0.0}).cellSize().maxCoeff();
  CHECK(cell == doctest::Approx(0.01));
  for (const std::vector<double>& isos : std::vector<std::vector<double>>{{0.0, 0.005}, {0.0, 0.05}, {0.0, -0.02}}) {
    CHECK(surfaceGrid(field, isos).cellSize().maxCoeff() == doctest::Approx(cell));
  }
  // A coarse finest level: the cell is capped at side/128, whatever δ.
  const ImplicitField smooth = radialField(2.0);
  const double side = smooth.bounds().sizes().maxCoeff();
  CHECK(surfaceGrid(smooth, {0.0, 0.005}).cellSize().maxCoeff() == doctest::Approx(side / 128));

  const FieldEvaluator evaluator(Device::reference(), smooth, Precision::Double);
  const std::vector<double> isos = {0.0, 0.02};
  SurfaceResult s = extractSurfaces(evaluator, smooth, isos);
  const double gridCell = s.grid.cellSize().maxCoeff();
  MeshFinishOptions full;
  full.deviationSamples = 0;  // every vertex and face centre (the default measures a 100k stride)
  const FinishResult f = finishSurfaces(evaluator, smooth, std::move(s.meshes), isos, gridCell, full);
  REQUIRE(f.meshes.size() == 2);
  for (std::size_t i = 0; i < 2; ++i) {
    CAPTURE(i);
    const MeshFinishReport& rep = f.reports[i];
    CHECK(rep.clean.collapses > 0);
    CHECK(rep.clean.float32DegenerateAfter == 0);
    CHECK_FALSE(rep.simplify.applied);
    REQUIRE(rep.deviationMeasured);
    CHECK(rep.deviation.samples == static_cast<std::size_t>(f.meshes[i].vertices.rows() + f.meshes[i].faces.rows()));
    CHECK(rep.deviation.side == doctest::Approx(side));
    CHECK(rep.deviation.relativeMax <= 1e-3);
    CHECK(rep.deviation.max > 0.0);
    CHECK(analyzeTopology(f.meshes[i]).watertight());
    // The first-order estimate agrees with the exact radial distance at the vertices.
    const double radius = [&] {  // |x| where f = iso, by bisection on the radial profile
      double lo = 0.0, hi = 2.0;
      for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        (smooth.value(Eigen::Vector3d(mid, 0, 0)) > isos[i] ? lo : hi) = mid;
      }
      return 0.5 * (lo + hi);
    }();
    CHECK(radialError(f.meshes[i], Eigen::Vector3d::Zero(), radius) <= rep.deviation.max * 1.05);
    // Capped: an even stride of the samples, whose max cannot exceed the full measure's.
    const LevelSetDeviation part = levelSetDeviation(evaluator, smooth, f.meshes[i], isos[i], 1000);
    CHECK(part.candidates == rep.deviation.samples + rep.deviation.flatSamples);
    CHECK(part.samples + part.flatSamples == 1000);
    CHECK(part.max <= rep.deviation.max * (1.0 + 1e-9));
    CHECK(part.mean == doctest::Approx(rep.deviation.mean).epsilon(0.5));
    // The default stride (100k samples): its mean and p99 are estimates of the full measure's.
    const LevelSetDeviation byDefault =
        levelSetDeviation(evaluator, smooth, f.meshes[i], isos[i], MeshFinishOptions{}.deviationSamples);
    CHECK(byDefault.samples + byDefault.flatSamples == std::min<std::size_t>(100000, part.candidates));
    CHECK(byDefault.max <= rep.deviation.max * (1.0 + 1e-9));
    CHECK(byDefault.mean == doctest::Approx(rep.deviation.mean).epsilon(0.05));
    CHECK(byDefault.p99 == doctest::Approx(rep.deviation.p99).epsilon(0.1));
  }
}

TEST_CASE("several meshes finished at once on the OpenCL device: the same meshes and reports as one at a time") {
  DUPLEXFIT_OPENCL_DEVICE(dev);
  // Three Wendland bumps of two sizes: level sets that are not spheres, three meshes of a few thousand
  // triangles each, so the workers' field evaluations interleave on the device.
  FieldLevel coarse, fine;
  coarse.sigma = 1.2;
  coarse.centres = Points(2, 3);
  coarse.centres << -0.2, 0.0, 0.0, 0.25, 0.05, -0.05;
  coarse.weights = Eigen::Vector2d(0.8, 0.7);
  fine.sigma = 0.35;
  fine.centres = Points(1, 3);
  fine.centres << 0.0, 0.3, 0.1;
  fine.weights = Eigen::VectorXd::Constant(1, 0.3);
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
  const ImplicitField field(Normalization{}, -0.5, {coarse, fine}, {}, bounds);
  const FieldEvaluator evaluator(dev, field, Precision::Float);
  const std::vector<double> isos = {0.0, 0.02, -0.03};
  const SurfaceResult s = extractSurfaces(evaluator, field, isos);
  for (const Mesh& m : s.meshes) REQUIRE(m.faces.rows() > 2000);
  const double cell = s.grid.cellSize().maxCoeff();
  MeshFinishOptions one, three;
  one.concurrentMeshes = 1;
  three.concurrentMeshes = 3;
  const FinishResult a = finishSurfaces(evaluator, field, s.meshes, isos, cell, one);
  const FinishResult b = finishSurfaces(evaluator, field, s.meshes, isos, cell, three);
  REQUIRE(a.meshes.size() == 3);
  REQUIRE(b.meshes.size() == 3);
  for (std::size_t i = 0; i < 3; ++i) {
    CAPTURE(i);
    CHECK(a.meshes[i].faces == b.meshes[i].faces);
    CHECK(a.meshes[i].vertices == b.meshes[i].vertices);
    CHECK(a.reports[i].clean.collapses == b.reports[i].clean.collapses);
    CHECK(a.reports[i].project.moved == b.reports[i].project.moved);
    CHECK(a.reports[i].project.splits == b.reports[i].project.splits);
    REQUIRE(b.reports[i].deviationMeasured);
    CHECK(a.reports[i].deviation.max == b.reports[i].deviation.max);
    CHECK(b.reports[i].deviation.relativeMax <= 1e-3);
    CHECK(analyzeTopology(b.meshes[i]).watertight());
  }
  // No mesh: nothing to do (and no division by the count).
  CHECK(finishSurfaces(evaluator, field, {}, {}, cell, three).meshes.empty());
  // Cancelled before any mesh is taken: Cancelled, whatever the workers.
  struct Stop : Interrupter {
    bool wasInterrupted(int) override { return true; }
  } stop;
  CHECK_THROWS_AS(finishSurfaces(evaluator, field, s.meshes, isos, cell, three, &stop), Cancelled);
}

TEST_CASE("simplification without meshoptimizer is a clear error") {
  if (simplificationAvailable()) DUPLEXFIT_SKIP("this build has meshoptimizer (the error cannot happen)");
  const Mesh m = sphereMesh(Eigen::Vector3d::Zero(), 0.5, 0.05);
  SimplifyOptions o;
  CHECK(simplifyMesh(m, o).mesh.faces.rows() == m.faces.rows());  // nothing asked: nothing needed
  o.maxTriangles = 100;
  CHECK_THROWS_WITH_AS(simplifyMesh(m, o), doctest::Contains("meshoptimizer"), InvalidArgument);
  MeshFinishOptions f;
  f.simplify.maxError = 0.01;
  CHECK_THROWS_WITH_AS(validateFinishOptions(f), doctest::Contains("meshoptimizer"), InvalidArgument);
}

TEST_CASE("simplification under a budget keeps the sphere closed and close") {
  if (!simplificationAvailable()) DUPLEXFIT_SKIP("this build has no meshoptimizer: simplification is disabled");
  const double r = 0.5;
  const Mesh m = cleanMesh(sphereMesh(Eigen::Vector3d::Zero(), r, 0.025)).mesh;
  REQUIRE(m.faces.rows() > 5000);
  SimplifyOptions o;
  o.maxTriangles = 2000;
  const SimplifyResult s = simplifyMesh(m, o);
  MESSAGE("meshoptimizer: " << s.report.duplicatePairsRemoved << " duplicate pairs removed, fallback " << s.report.fallback);
  CHECK(s.report.applied);
  CHECK(s.report.topologyKept);
  CHECK(s.report.facesBefore == static_cast<std::size_t>(m.faces.rows()));
  CHECK(s.report.facesAfter <= 2000);
  CHECK(s.report.facesAfter > 1000);
  CHECK(s.mesh.faces.rows() == static_cast<Eigen::Index>(s.report.facesAfter));
  const MeshCheck c = checkMesh(s.mesh);
  CHECK(c.watertight);
  CHECK(c.manifold);
  CHECK(c.genusKnown);
  CHECK(c.genus == 0);
  CHECK(c.selfIntersections == 0);
  CHECK(radialError(s.mesh, Eigen::Vector3d::Zero(), r) < 0.01);
  // An error bound alone: the simplifier stops at it.
  SimplifyOptions bound;
  bound.maxError = 1e-3;
  const SimplifyResult b = simplifyMesh(m, bound);
  CHECK(b.report.topologyKept);
  CHECK(b.report.facesAfter < b.report.facesBefore);
  CHECK((b.report.fallback || b.report.resultError <= 1e-3 * 1.01));
  CHECK(radialError(b.mesh, Eigen::Vector3d::Zero(), r) < 3e-3);
  bound.maxError = -1.0;
  CHECK_THROWS_AS(simplifyMesh(m, bound), InvalidArgument);
}

TEST_CASE("the library's own edge-collapse simplifier keeps a sphere and a torus closed 2-manifolds") {
  const Mesh sphere = sphereMesh(Eigen::Vector3d::Zero(), 0.5, 0.025);
  const double R = 0.5, rt = 0.2, cell = 0.02;
  const GridSpec grid = GridSpec::fromCellSize(
      Eigen::AlignedBox3d(Eigen::Vector3d(-0.8, -0.8, -0.3), Eigen::Vector3d(0.8, 0.8, 0.3)), cell);
  const FieldSampler ring = [R, rt](const Points& q, Eigen::VectorXd& v) {
    v.resize(q.rows());
    for (Eigen::Index i = 0; i < q.rows(); ++i) v[i] = rt - std::hypot(std::hypot(q(i, 0), q(i, 1)) - R, q(i, 2));
  };
  const Mesh torus = polygonize(ring, grid, {0.0}).meshes[0];
  for (const Mesh* m : {&sphere, &torus}) {
    const MeshTopology before = analyzeTopology(*m);
    REQUIRE(before.watertight());
    std::size_t collapses = 0;
    const Mesh s = detail::collapseSimplify(*m, 1500, 0.0, &collapses);
    CHECK(collapses > 0);
    CHECK(s.faces.rows() <= 1500);
    CHECK(s.faces.rows() >= 1400);
    const MeshCheck c = checkMesh(s);
    CHECK(c.watertight);
    CHECK(c.manifold);
    CHECK(c.oriented);
    CHECK(c.topology.components == 1);
    CHECK(c.topology.eulerCharacteristic == before.eulerCharacteristic);
    CHECK(c.selfIntersections == 0);
    CHECK(c.quality.float32DegenerateFaces == 0);
  }
  // An error bound alone stops the collapses before the surface moves farther than it.
  const Mesh bounded = detail::collapseSimplify(sphere, 0, 1e-3);
  CHECK(bounded.faces.rows() < sphere.faces.rows() / 2);
  CHECK(radialError(bounded, Eigen::Vector3d::Zero(), 0.5) <= radialError(sphere, Eigen::Vector3d::Zero(), 0.5) + 1e-3);
  CHECK(analyzeTopology(bounded).watertight());
}

}  // TEST_SUITE

namespace {

/// The sampler of f = r − |x − c| with its gradient −(x − c)/|x − c|.
FieldGradientSampler sphereSampler(const Eigen::Vector3d& c, double r) {
  return [c, r](const Points& q, Eigen::VectorXd& v, Points& g) {
    v.resize(q.rows());
    g.resize(q.rows(), 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      const Eigen::Vector3d d = q.row(i).transpose() - c;
      v[i] = r - d.norm();
      g.row(i) = -d.transpose() / d.norm();
    }
  };
}

/// Checks the first-order values a projection hands on (ProjectResult::known): each known one is what an
/// evaluation at its vertex or face centre gives now, bit for bit (a value left from before a move back or
/// a split fails here). Returns {known vertices, known centres}.
std::pair<std::size_t, std::size_t> checkKnownFirstOrder(const FieldGradientSampler& sampler, const ProjectResult& p,
                                                         double iso) {
  const Mesh& m = p.mesh;
  REQUIRE(p.known.vertices.size() == static_cast<std::size_t>(m.vertices.rows()));
  REQUIRE(p.known.centres.size() == static_cast<std::size_t>(m.faces.rows()));
  Points at(m.vertices.rows() + m.faces.rows(), 3);
  at.topRows(m.vertices.rows()) = m.vertices;
  for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
    at.row(m.vertices.rows() + f) =
        (m.vertices.row(m.faces(f, 0)) + m.vertices.row(m.faces(f, 1)) + m.vertices.row(m.faces(f, 2))) / 3.0;
  }
  Eigen::VectorXd v;
  Points g;
  sampler(at, v, g);
  std::size_t vertices = 0, centres = 0, wrong = 0;
  for (Eigen::Index i = 0; i < at.rows(); ++i) {
    const bool vertex = i < m.vertices.rows();
    const double k = vertex ? p.known.vertices[static_cast<std::size_t>(i)]
                            : p.known.centres[static_cast<std::size_t>(i - m.vertices.rows())];
    if (std::isnan(k)) continue;
    (vertex ? vertices : centres) += 1;
    const double gn = g.row(i).norm();
    const double want = gn >= 1e-6 ? std::abs(v[i] - iso) / gn : -1.0;
    wrong += k == want ? 0 : 1;
  }
  CHECK(wrong == 0);
  return {vertices, centres};
}

/// The deviation measures' figures, all but the time.
void checkSameDeviation(const LevelSetDeviation& a, const LevelSetDeviation& b) {
  CHECK(a.candidates == b.candidates);
  CHECK(a.samples == b.samples);
  CHECK(a.flatSamples == b.flatSamples);
  CHECK(a.refinedSamples == b.refinedSamples);
  CHECK(a.localSamples == b.localSamples);
  CHECK(a.max == b.max);
  CHECK(a.mean == b.mean);
  CHECK(a.rms == b.rms);
  CHECK(a.p99 == b.p99);
  CHECK(a.p999 == b.p999);
  CHECK(a.maxAt == b.maxAt);
  CHECK(a.aboveLimit == b.aboveLimit);
  CHECK(a.aboveLimitAt == b.aboveLimitAt);
  CHECK(a.nearLimitAt == b.nearLimitAt);
}

}  // namespace

TEST_SUITE("surfaces") {
TEST_CASE("level-set deviation: a strided measure also finds the top of a small bump") {
  // A sphere mesh moved exactly onto the sphere, then a bump of a few rings pushed outward (5e-3 at its
  // top, five times the limit of a unit side). The stride lands on the bump's flanks at best; the local pass
  // around them measures every vertex and face centre there, so the max is the full measure's.
  const Eigen::Vector3d c = Eigen::Vector3d::Zero();
  const double r = 0.5;
  Mesh m = cleanMesh(sphereMesh(c, r, 0.02)).mesh;
  const Eigen::Vector3d top = r * Eigen::Vector3d(0.3, 0.4, 0.8).normalized();
  for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
    Eigen::Vector3d p = m.vertices.row(v).transpose().normalized() * r;
    const double d = (p - top).norm();
    if (d < 0.06) p *= 1.0 + 0.01 * (1.0 - d / 0.06) * (1.0 - d / 0.06);
    m.vertices.row(v) = p.transpose();
  }
  const FieldGradientSampler sampler = sphereSampler(c, r);
  const LevelSetDeviation full = levelSetDeviation(sampler, m, 0.0, 1.0, 0);
  REQUIRE(full.max > 4e-3);
  CHECK(full.localSamples == 0);  // every candidate measured: nothing local to add
  const std::size_t stride = full.candidates / 20;
  const LevelSetDeviation part = levelSetDeviation(sampler, m, 0.0, 1.0, stride);
  CHECK(part.samples + part.flatSamples == stride);
  CHECK(part.localSamples > 0);
  CHECK(part.localSamples <= stride);
  CHECK(part.max == doctest::Approx(full.max).epsilon(1e-9));
  CHECK((part.maxAt - full.maxAt).norm() < 0.01);
  // The spread still comes from the stride alone: fewer samples beyond the limit than the full measure.
  CHECK(part.aboveLimit < full.aboveLimit);
  // A face index out of range is a clear error, not a read past the vertices.
  Mesh bad = m;
  bad.faces(3, 1) = static_cast<std::int32_t>(m.vertices.rows());
  CHECK_THROWS_WITH_AS(levelSetDeviation(sampler, bad, 0.0, 1.0, stride), doctest::Contains("face 3"), InvalidArgument);
}

TEST_CASE("projection moves a coarse sphere onto its level set and splits it to the target") {
  const Eigen::Vector3d c(0.1, -0.2, 0.3);
  const double r = 0.5, cell = 0.1, iso = 0.05;  // a coarse grid: faces far off the sphere of radius r − iso
  const Mesh m = cleanMesh(sphereMesh(c, r, cell, iso)).mesh;
  const FieldGradientSampler sampler = sphereSampler(c, r);
  const MeshTopology before = analyzeTopology(m);
  const double side = 1.0;
  const LevelSetDeviation d0 = levelSetDeviation(sampler, m, iso, side);
  ProjectOptions o;
  o.target = 2e-3;
  o.maxGrowth = 100.0;
  o.rounds = 20;
  const ProjectResult p = projectToLevelSet(sampler, m, iso, side, o);
  CAPTURE(d0.max);
  CHECK(p.report.applied);
  CHECK(p.report.moved > 0);
  CHECK(p.report.splits > 0);
  CHECK(p.report.facesAfter == p.report.facesBefore + 2 * p.report.splits);
  CHECK(p.report.verticesAfter == p.report.verticesBefore + p.report.splits);
  // Every vertex on the sphere of radius r − iso (to the Newton tolerance), except refused moves.
  const double exact = r - iso;
  CHECK(radialError(p.mesh, c, exact) <= 1e-4);
  // Every face centre within the target: the sagitta of the split faces (measured exactly: radial).
  double worstCentre = 0.0;
  for (Eigen::Index f = 0; f < p.mesh.faces.rows(); ++f) {
    const Eigen::Vector3d x = (p.mesh.vertices.row(p.mesh.faces(f, 0)) + p.mesh.vertices.row(p.mesh.faces(f, 1)) +
                               p.mesh.vertices.row(p.mesh.faces(f, 2))).transpose() / 3.0;
    worstCentre = std::max(worstCentre, std::abs((x - c).norm() - exact));
  }
  CHECK(worstCentre <= o.target * 1.01);
  CHECK(d0.max > 3 * worstCentre);  // it was far worse before
  const MeshTopology after = analyzeTopology(p.mesh);
  CHECK(after.watertight());
  CHECK(after.manifold());
  CHECK(after.oriented());
  CHECK(after.components == before.components);
  CHECK(after.eulerCharacteristic == before.eulerCharacteristic);
  CHECK(checkMesh(p.mesh).valid());
  CHECK(signedVolume(p.mesh) > 0.0);

  // Predicting the first round's centres from the corners' gradients changes nothing: a predicted face
  // (its centre within an eighth of the target on a sphere) is never one the evaluation would mark. Same
  // mesh, bit for bit, with fewer evaluations; with a loose target most faces are predicted.
  for (const double target : {2e-3, 1e-2, 3e-2}) {
    CAPTURE(target);
    ProjectOptions on = o, off = o;
    on.target = off.target = target;
    CHECK_FALSE(off.estimateCentres);  // opt-in
    on.estimateCentres = true;
    const ProjectResult a = projectToLevelSet(sampler, m, iso, side, on);
    const ProjectResult b = projectToLevelSet(sampler, m, iso, side, off);
    CHECK(a.mesh.vertices == b.mesh.vertices);
    CHECK(a.mesh.faces == b.mesh.faces);
    CHECK(b.report.centresPredicted == 0);
    CHECK(a.report.centresPredicted + a.report.centresEvaluated <= b.report.centresEvaluated);
    MESSAGE("target " << target << ": " << a.report.centresPredicted << " centres predicted, "
                      << a.report.centresEvaluated << " evaluated (" << b.report.centresEvaluated
                      << " without the prediction), " << a.report.splits << " splits of " << m.faces.rows() << " faces");
    if (target == 2e-3) {  // mixed: some faces predicted, others evaluated and split
      CHECK(a.report.centresPredicted > 0);
      CHECK(a.report.splits > 0);
    }
    if (target == 3e-2) CHECK(a.report.centresPredicted > static_cast<std::size_t>(m.faces.rows()) / 2);
  }

  // The projection hands the deviation measure the first-order values it evaluated where its vertices
  // and face centres stand (the vertices' Newton ends, the centres it tested, the splits' new vertices;
  // not the predicted centres): the same measure, strided or full, with fewer evaluations.
  {
    ProjectOptions predicted = o;
    predicted.estimateCentres = true;
    const ProjectResult a = projectToLevelSet(sampler, m, iso, side, predicted);
    const auto [knownVertices, knownCentres] = checkKnownFirstOrder(sampler, a, iso);
    CHECK(knownVertices > static_cast<std::size_t>(a.mesh.vertices.rows()) / 2);
    CHECK(knownCentres > 0);
    CHECK(knownCentres < static_cast<std::size_t>(a.mesh.faces.rows()));  // the predicted ones are not known
    std::size_t asked = 0;
    const FieldGradientSampler counting = [&](const Points& q, Eigen::VectorXd& v, Points& g) {
      asked += static_cast<std::size_t>(q.rows());
      sampler(q, v, g);
    };
    // Stopped after one round of splits: the split faces' centres were not evaluated again.
    ProjectOptions short1 = predicted;
    short1.rounds = 1;
    const ProjectResult b = projectToLevelSet(sampler, m, iso, side, short1);
    CHECK(b.report.splits > 0);
    checkKnownFirstOrder(sampler, b, iso);
    checkSameDeviation(levelSetDeviation(sampler, b.mesh, iso, side), levelSetDeviation(sampler, b.mesh, iso, side, 0, &b.known));
    for (const std::size_t samples : {std::size_t{0}, std::size_t{200}}) {
      CAPTURE(samples);
      asked = 0;
      const LevelSetDeviation plain = levelSetDeviation(counting, a.mesh, iso, side, samples);
      const std::size_t plainAsked = asked;
      asked = 0;
      const LevelSetDeviation helped = levelSetDeviation(counting, a.mesh, iso, side, samples, &a.known);
      checkSameDeviation(plain, helped);
      CHECK(asked < plainAsked);
    }
  }

  // Without a target: the vertices move, nothing is split. A face budget stops the splits.
  ProjectOptions still;
  const ProjectResult q = projectToLevelSet(sampler, m, iso, side, still);
  CHECK(q.report.splits == 0);
  CHECK(q.mesh.faces.rows() == m.faces.rows());
  CHECK(radialError(q.mesh, c, exact) <= 1e-4);
  ProjectOptions budget = o;
  budget.maxFaces = static_cast<std::size_t>(m.faces.rows()) + 40;
  const ProjectResult b = projectToLevelSet(sampler, m, iso, side, budget);
  CHECK(b.mesh.faces.rows() <= m.faces.rows() + 40);
  CHECK(b.report.markedLeft > 0);
  // Deterministic.
  const ProjectResult again = projectToLevelSet(sampler, m, iso, side, o);
  CHECK(again.mesh.vertices == p.mesh.vertices);
  CHECK(again.mesh.faces == p.mesh.faces);
  // Bad options and indices.
  ProjectOptions bad;
  bad.target = -1.0;
  CHECK_THROWS_AS(projectToLevelSet(sampler, m, iso, side, bad), InvalidArgument);
  Mesh broken = m;
  broken.faces(3, 1) = static_cast<std::int32_t>(m.vertices.rows());
  CHECK_THROWS_WITH_AS(projectToLevelSet(sampler, broken, iso, side, o), doctest::Contains("face 3"), InvalidArgument);
}

}  // TEST_SUITE

namespace {

/// A flat n × n grid of squares over [x0, x0 + w] × [0, 1] at height z, two triangles each, facing +z.
Mesh gridSheet(double x0, double w, double z, int n) {
  Mesh m;
  m.vertices.resize((n + 1) * (n + 1), 3);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) m.vertices.row(j * (n + 1) + i) << x0 + w * i / n, 1.0 * j / n, z;
  }
  m.faces.resize(2 * n * n, 3);
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      m.faces.row(2 * (j * n + i)) << a, b, d;
      m.faces.row(2 * (j * n + i) + 1) << a, d, c;
    }
  }
  return m;
}

Mesh joined(const Mesh& a, const Mesh& b) {
  Mesh m;
  m.vertices.resize(a.vertices.rows() + b.vertices.rows(), 3);
  m.vertices << a.vertices, b.vertices;
  m.faces.resize(a.faces.rows() + b.faces.rows(), 3);
  m.faces << a.faces, b.faces.array() + static_cast<std::int32_t>(a.vertices.rows());
  return m;
}

}  // namespace

TEST_SUITE("surfaces") {

TEST_CASE("projection undoes the moves that make two sheets cross, testing only what moved after the first round") {
  // Two sheets at z = 0.15 and 0.25, overlapping over x in [0.5, 1]; the level set z = 0.2 lies between
  // them, so the projection lays both on one plane there (coplanar overlapping triangles intersect).
  const Mesh m = joined(gridSheet(0.0, 1.0, 0.15, 10), gridSheet(0.5, 1.0, 0.25, 10));
  const FieldGradientSampler sampler = [](const Points& q, Eigen::VectorXd& v, Points& g) {
    v = 0.2 - q.col(2).array();
    g = Points::Zero(q.rows(), 3);
    g.col(2).setConstant(-1.0);
  };
  REQUIRE(findSelfIntersections(m).count == 0);
  ProjectOptions keep;
  keep.undoSelfIntersections = false;
  const ProjectResult crossed = projectToLevelSet(sampler, m, 0.0, 1.0, keep);
  CHECK(crossed.report.moved == static_cast<std::size_t>(m.vertices.rows()));
  CheckOptions all;
  all.listedPairs = std::numeric_limits<std::size_t>::max();
  const SelfIntersections full = findSelfIntersections(crossed.mesh, all);
  CHECK(full.complete);
  CHECK(full.count > 50);
  CHECK(full.pairs.size() == full.count);
  CHECK(checkMesh(crossed.mesh, all).selfIntersections == full.count);
  // A subset finds exactly the pairs with a face in it, each once.
  std::vector<std::int64_t> subset;
  for (std::int64_t f = 0; f < crossed.mesh.faces.rows(); f += 3) subset.push_back(f);
  std::vector<std::pair<std::int64_t, std::int64_t>> expected;
  for (const auto& p : full.pairs) {
    if (p.first % 3 == 0 || p.second % 3 == 0) expected.push_back(p);
  }
  const SelfIntersections part = findSelfIntersections(crossed.mesh, all, &subset);
  CHECK(part.count == expected.size());
  CHECK(part.pairs == expected);
  // A subset in one corner of the overlap: the tree is then built over the faces near it only, and the
  // pairs must still be exactly those of the full list with a face in it.
  std::vector<std::int64_t> corner;
  std::vector<char> inCorner(static_cast<std::size_t>(crossed.mesh.faces.rows()), 0);
  for (std::int64_t f = 0; f < crossed.mesh.faces.rows(); ++f) {
    const Eigen::RowVector3d c = (crossed.mesh.vertices.row(crossed.mesh.faces(f, 0)) +
                                  crossed.mesh.vertices.row(crossed.mesh.faces(f, 1)) +
                                  crossed.mesh.vertices.row(crossed.mesh.faces(f, 2))) / 3.0;
    if (c.x() > 0.6 && c.x() < 0.75 && c.y() > 0.2 && c.y() < 0.4) {
      corner.push_back(f);
      inCorner[static_cast<std::size_t>(f)] = 1;
    }
  }
  REQUIRE(corner.size() > 4);
  REQUIRE(corner.size() * 10 < static_cast<std::size_t>(crossed.mesh.faces.rows()));
  std::vector<std::pair<std::int64_t, std::int64_t>> expectedCorner;
  for (const auto& p : full.pairs) {
    if (inCorner[static_cast<std::size_t>(p.first)] || inCorner[static_cast<std::size_t>(p.second)]) expectedCorner.push_back(p);
  }
  REQUIRE(!expectedCorner.empty());
  const SelfIntersections local = findSelfIntersections(crossed.mesh, all, &corner);
  CHECK(local.complete);
  CHECK(local.pairs == expectedCorner);
  CHECK(local.count == expectedCorner.size());
  const std::vector<std::int64_t> none;
  CHECK(findSelfIntersections(crossed.mesh, all, &none).count == 0);
  std::vector<std::int64_t> outside{crossed.mesh.faces.rows()};
  CHECK_THROWS_AS(findSelfIntersections(crossed.mesh, all, &outside), InvalidArgument);

  // With the undo: no pair is left (tested over the whole mesh), the sheets stay on the level set away
  // from the overlap, and not everything went back.
  const ProjectResult p = projectToLevelSet(sampler, m, 0.0, 1.0, ProjectOptions{});
  CHECK(p.report.selfIntersectionsFound == full.count);
  CHECK(p.report.reverted > 0);
  // What moved back, and the centres of its faces, are not handed on as known (no stale values).
  const auto known = checkKnownFirstOrder(sampler, p, 0.0);
  CHECK(known.first + p.report.reverted <= static_cast<std::size_t>(p.mesh.vertices.rows()));
  checkSameDeviation(levelSetDeviation(sampler, p.mesh, 0.0, 1.0), levelSetDeviation(sampler, p.mesh, 0.0, 1.0, 0, &p.known));
  CHECK(p.report.reverted < static_cast<std::size_t>(m.vertices.rows()));
  CHECK(findSelfIntersections(p.mesh, all).count == 0);
  CHECK(p.report.selfIntersectionsChecked);
  CHECK(p.report.selfIntersectionsLeft == 0);
  CHECK_FALSE(crossed.report.selfIntersectionsChecked);
  CHECK(checkMesh(p.mesh).quality.float32DegenerateFaces == 0);
  int farOnLevel = 0, far = 0;
  for (Eigen::Index v = 0; v < p.mesh.vertices.rows(); ++v) {
    const double x = p.mesh.vertices(v, 0);
    if (x > 0.25 && x < 1.25) continue;
    ++far;
    farOnLevel += std::abs(p.mesh.vertices(v, 2) - 0.2) <= 1e-5 ? 1 : 0;
  }
  CHECK(far > 40);
  CHECK(farOnLevel == far);
}

TEST_CASE("projection leaves crossings of the extracted surface alone: only what it moved is undone") {
  // Two coplanar sheets overlapping over x in [0.5, 1] on the level set z = 0.2 (crossing pairs that no
  // vertex move made), and a third sheet at z = 0.15 far from them, which the projection moves onto the
  // level set without crossing anything. The undo must not take the third sheet back (the old first round
  // tested every pair, seeded the unmoved pairs and widened its rings until the last round moved every
  // vertex back).
  const Mesh m = joined(joined(gridSheet(0.0, 1.0, 0.2, 10), gridSheet(0.5, 1.0, 0.2, 10)), gridSheet(3.0, 1.0, 0.15, 10));
  const FieldGradientSampler sampler = [](const Points& q, Eigen::VectorXd& v, Points& g) {
    v = 0.2 - q.col(2).array();
    g = Points::Zero(q.rows(), 3);
    g.col(2).setConstant(-1.0);
  };
  CheckOptions all;
  all.listedPairs = std::numeric_limits<std::size_t>::max();
  const SelfIntersections before = findSelfIntersections(m, all);
  REQUIRE(before.count > 50);
  const ProjectResult p = projectToLevelSet(sampler, m, 0.0, 1.0, ProjectOptions{});
  CHECK(p.report.moved == 121);
  CHECK(p.report.selfIntersectionsFound == 0);
  CHECK(p.report.reverted == 0);
  const SelfIntersections after = findSelfIntersections(p.mesh, all);
  CHECK(after.pairs == before.pairs);
  // Nothing the projection moved crosses: none left (the extracted surface's own pairs are not its).
  CHECK(p.report.selfIntersectionsChecked);
  CHECK(p.report.selfIntersectionsLeft == 0);
  int moved = 0;
  for (Eigen::Index v = 0; v < p.mesh.vertices.rows(); ++v) {
    CHECK(std::abs(p.mesh.vertices(v, 2) - 0.2) <= 1e-12);
    moved += p.mesh.vertices(v, 0) >= 3.0 ? 1 : 0;
  }
  CHECK(moved == 121);
}

}  // TEST_SUITE
