// The neck pass's local replacement (lib/surfaces/splice.hpp): a zone of a finished sphere replaced by a
// finer extraction there, joined by a band; the result closed, oriented, not self-intersecting, on the
// sphere, the faces outside the zone untouched; and the refusals when the boundaries do not pair up.
#include <doctest/doctest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <set>
#include <vector>

#include "duplexfit/field.hpp"
#include "duplexfit/measure.hpp"
#include "duplexfit/mesh_finish.hpp"
#include "duplexfit/polygonize.hpp"
#include "duplexfit/surfaces.hpp"
#include "surfaces/splice.hpp"

namespace {

using namespace duplexfit;

/// f = −0.5 + φ(|x|/2) (one C2 Wendland bump): its level sets are spheres, |∇f| ≈ 1 near f = 0.
ImplicitField bump() {
  FieldLevel level;
  level.sigma = 2.0;
  level.centres = Points::Zero(1, 3);
  level.weights = Eigen::VectorXd::Ones(1);
  const Eigen::AlignedBox3d bounds(Eigen::Vector3d::Constant(-0.7), Eigen::Vector3d::Constant(0.7));
  return ImplicitField(Normalization{}, -0.5, {level}, {}, bounds);
}

/// |x| where the bump's f = 0, by bisection.
double zeroRadius(const ImplicitField& f) {
  double lo = 0.0, hi = 2.0;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    (f.value(Eigen::Vector3d(mid, 0, 0)) > 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

/// The bump's zero level extracted and finished as the pipelines do, and the splice's steps on it.
struct FinishedSphere {
  ImplicitField field = bump();
  FieldEvaluator evaluator{Device::reference(), field, Precision::Double};
  double radius = zeroRadius(field);
  SurfaceOptions options;
  GridSpec grid;
  Mesh mesh = [this] {
    SurfaceResult first = extractSurfaces(evaluator, field, {0.0}, options);
    grid = first.grid;
    FinishResult finished =
        finishSurfaces(evaluator, field, std::move(first.meshes), {0.0}, grid.cellSize().maxCoeff(), options.finish);
    return std::move(finished.meshes[0]);
  }();
  double cell = grid.cellSize().maxCoeff(), side = field.bounds().sizes().maxCoeff();

  /// The level set extracted again with `cells` refined one level more.
  Mesh extractedAgain(const std::vector<std::array<int, 3>>& cells) const {
    PolygonizeOptions po = surfacePolygonizeOptions(field, options);
    po.refineDeeperCells = cells;
    return polygonize(valueSampler(evaluator), grid, {0.0}, po).meshes[0];
  }
  detail::SpliceResult splice(const Mesh& extracted, const std::vector<std::int64_t>& inner,
                              const std::vector<std::int64_t>& outer) const {
    return detail::spliceZone(mesh, extracted, grid, inner, outer, detail::fieldGradientSampler(evaluator), 0.0, side,
                              detail::finishCleanOptions(options.finish, cell),
                              detail::finishProjectOptions(options.finish, side, cell));
  }
  /// A splice's result is one closed oriented sphere without crossing faces, its new vertices within
  /// `tolerance` (a fraction of the side) of the sphere and its patch within the deviation target.
  void checkClosedOnTheSphere(const detail::SpliceResult& s, double tolerance) const {
    const MeshTopology t = analyzeTopology(s.mesh);
    CHECK(t.watertight());
    CHECK(t.manifold());
    CHECK(t.oriented());
    CHECK(t.components == 1);
    CHECK(t.eulerCharacteristic == 2);
    CheckOptions all;
    CHECK(findSelfIntersections(s.mesh, all).count == 0);
    double worst = 0.0;
    for (Eigen::Index v = 0; v < s.patch.vertices.rows(); ++v) {
      worst = std::max(worst, std::abs(s.patch.vertices.row(v).norm() - radius));
    }
    CHECK(worst <= tolerance * side);
    CHECK(levelSetDeviation(evaluator, field, s.patch, 0.0, 0).relativeMax <= 1e-3);
  }
};

}  // namespace

TEST_SUITE("surfaces") {

TEST_CASE("the neck pass's splice: a zone of a finished sphere replaced by a finer extraction, closed and on the sphere") {
  const FinishedSphere sphere;
  const GridSpec& grid = sphere.grid;
  const Mesh& mesh = sphere.mesh;
  REQUIRE(analyzeTopology(mesh).watertight());

  // The cells around a point of the sphere refined one level more, the level set extracted again.
  const std::array<int, 3> centre = detail::cellOf(grid, sphere.radius * Eigen::Vector3d(1.0, 0.3, 0.2).normalized());
  std::vector<std::array<int, 3>> cells;
  for (int dz = -2; dz <= 2; ++dz) {
    for (int dy = -2; dy <= 2; ++dy) {
      for (int dx = -2; dx <= 2; ++dx) cells.push_back({centre[0] + dx, centre[1] + dy, centre[2] + dz});
    }
  }
  const Mesh again = sphere.extractedAgain(cells);
  const std::vector<std::int64_t> inner = detail::dilatedCells(grid, cells, 2);
  const std::vector<std::int64_t> outer = detail::dilatedCells(grid, cells, 3);
  CHECK(inner.size() == 9u * 9u * 9u);
  CHECK(outer.size() == 11u * 11u * 11u);
  const detail::SpliceResult s = sphere.splice(again, inner, outer);
  INFO(s.why);
  REQUIRE(s.ok);
  CHECK(s.loops == 1);  // a disc of the sphere
  CHECK(s.removedFaces > 100);
  CHECK(s.bandFaces > 0);
  // The patch is finer than what it replaced (three levels of refinement there instead of two or none).
  CHECK(s.patch.faces.rows() > static_cast<Eigen::Index>(s.removedFaces));
  CHECK(s.removed.faces.rows() == static_cast<Eigen::Index>(s.removedFaces));
  // On the sphere: the new vertices projected onto it (the band's faces and the patch's within the target).
  sphere.checkClosedOnTheSphere(s, 1e-5);
  CHECK(s.mesh.faces.rows() == mesh.faces.rows() - static_cast<Eigen::Index>(s.removedFaces) +
                                   static_cast<Eigen::Index>(s.newFaces.size()));
  // Every face outside the zone is the finished mesh's, the same three points.
  std::set<std::array<double, 9>> before, after;
  const auto key = [](const Mesh& m, Eigen::Index f) {
    std::array<double, 9> k{};
    for (int c = 0; c < 3; ++c) {
      for (int a = 0; a < 3; ++a) k[static_cast<std::size_t>(3 * c + a)] = m.vertices(m.faces(f, c), a);
    }
    return k;
  };
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) before.insert(key(mesh, f));
  std::set<std::int64_t> fresh(s.newFaces.begin(), s.newFaces.end());
  std::size_t old = 0, changed = 0;
  for (Eigen::Index f = 0; f < s.mesh.faces.rows(); ++f) {
    if (fresh.count(f) != 0) continue;
    changed += before.count(key(s.mesh, f)) == 1 ? 0 : 1;
    ++old;
  }
  CHECK(changed == 0);
  CHECK(old == static_cast<std::size_t>(mesh.faces.rows()) - s.removedFaces);

  // Refused, nothing made: a patch with no face in the zone (one hole loop, no patch loop) and an inner zone
  // that reaches past the outer one (the boundaries cross: not the same number of loops, or too far).
  const detail::SpliceResult none = sphere.splice(Mesh{}, inner, outer);
  CHECK_FALSE(none.ok);
  CHECK(none.why.find("boundary loops") != std::string::npos);
  CHECK(none.mesh.faces.rows() == 0);
  const std::vector<std::int64_t> nowhere = detail::dilatedCells(grid, {{0, 0, 0}}, 1);  // a corner: no face
  const detail::SpliceResult empty = sphere.splice(again, nowhere, nowhere);
  CHECK_FALSE(empty.ok);
  CHECK(empty.why == "no face of the mesh in the zone");
}

TEST_CASE("the neck pass's splice where the level set grazes the zone's boundary: the patch follows the hole") {
  // A flat slab of cells just above the sphere's pole: the inner zone's lowest layer holds the pole, the
  // outer zone reaches a layer lower, so the sphere's cap in the outer zone is much wider than in the
  // inner one (a nearly tangent cut). The patch is the extraction's faces about a cell inside the hole,
  // not those of the inner zone (whose boundary would run several cells from the hole's).
  const FinishedSphere sphere;
  const GridSpec& grid = sphere.grid;
  const Mesh& mesh = sphere.mesh;
  const double cell = sphere.cell;
  const std::array<int, 3> pole = detail::cellOf(grid, Eigen::Vector3d(0.0, 0.0, sphere.radius));
  std::vector<std::array<int, 3>> cells;
  for (int dz = 2; dz <= 4; ++dz) {
    for (int dy = -12; dy <= 12; ++dy) {
      for (int dx = -12; dx <= 12; ++dx) cells.push_back({pole[0] + dx, pole[1] + dy, pole[2] + dz});
    }
  }
  const std::vector<std::int64_t> inner = detail::dilatedCells(grid, cells, 2);
  const std::vector<std::int64_t> outer = detail::dilatedCells(grid, cells, 3);
  // The caps: the mesh's faces in each zone, the farthest from the pole's axis.
  const auto capRadius = [&](const std::vector<std::int64_t>& zone) {
    double r = 0.0;
    for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
      const Eigen::Vector3d c =
          (mesh.vertices.row(mesh.faces(f, 0)) + mesh.vertices.row(mesh.faces(f, 1)) + mesh.vertices.row(mesh.faces(f, 2))) / 3.0;
      const std::array<int, 3> id = detail::cellOf(grid, c);
      if (std::binary_search(zone.begin(), zone.end(), id[0] + std::int64_t{grid.cells(0)} * (id[1] + std::int64_t{grid.cells(1)} * id[2]))) {
        r = std::max(r, std::hypot(c.x(), c.y()));
      }
    }
    return r;
  };
  INFO("cell " << cell << ", cap radius in the inner zone " << capRadius(inner) << ", in the outer " << capRadius(outer));
  REQUIRE(capRadius(outer) - capRadius(inner) > 3.0 * cell);  // the case: inner-zone rims would not pair up
  const detail::SpliceResult s = sphere.splice(sphere.extractedAgain(cells), inner, outer);
  INFO(s.why);
  REQUIRE(s.ok);
  CHECK(s.loops == 1);
  // (A handful of the band's moves are refused by the projection's angle test, which leaves those
  // vertices where the extraction put them: within a tenth of the deviation target, not 1e-5 of the side.)
  sphere.checkClosedOnTheSphere(s, 1e-4);
}

TEST_CASE("the neck pass's boxes: one per cluster of cells, a margin around, overlapping ones merged") {
  const GridSpec grid = GridSpec::fromCellSize(Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(1.0)), 0.05);
  REQUIRE(grid.cells(0) == 20);
  const auto ids = [&](std::vector<std::array<int, 3>> cells) { return detail::dilatedCells(grid, cells, 0); };
  // Two clusters far apart: two boxes, each its cluster grown by the margin (clipped at the grid).
  const std::vector<std::array<int, 6>> two = detail::zoneBoxes(grid, ids({{1, 1, 1}, {2, 1, 1}, {15, 15, 15}}), 2);
  REQUIRE(two.size() == 2);
  CHECK(two[0] == std::array<int, 6>{0, 0, 0, 4, 3, 3});
  CHECK(two[1] == std::array<int, 6>{13, 13, 13, 17, 17, 17});
  // Diagonal neighbours are one cluster; clusters whose grown boxes overlap become one box.
  CHECK(detail::zoneBoxes(grid, ids({{5, 5, 5}, {6, 6, 6}}), 1).size() == 1);
  const std::vector<std::array<int, 6>> merged = detail::zoneBoxes(grid, ids({{5, 5, 5}, {9, 5, 5}}), 2);
  REQUIRE(merged.size() == 1);
  CHECK(merged[0] == std::array<int, 6>{3, 3, 3, 11, 7, 7});
  CHECK(detail::cellOf(grid, Eigen::Vector3d(0.07, -1.0, 2.0)) == std::array<int, 3>{1, 0, 19});
}

}  // TEST_SUITE
