// The printable shell on analytic fields: the joined mesh of a sphere's level sets (closed, oriented,
// the exact volume, the offset's faces reversed), two crossing spheres flagged as intersecting, the drain
// holes' distance function and its derivatives, a drained sphere shell (one closed component of genus 0,
// the exact volume of the hole removed), automatic holes at the cavity's lowest point, and bad input.
#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/polygonize.hpp"
#include "duplexfit/shell.hpp"
#include "measure/measure_shapes.hpp"

namespace {

using namespace duplexfit;

constexpr double kPi = 3.14159265358979323846;
constexpr double kR = 0.5;  // the sphere f = R − |x|

const FieldSampler sphereField = [](const Points& q, Eigen::VectorXd& values) {
  values = (kR - q.rowwise().norm().array()).matrix();
};

GridSpec sphereGrid() {
  return GridSpec::fromCellSize(Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.6), Eigen::Vector3d::Constant(0.6)),
                                0.0125);
}

/// The zero level and the level δ of the sphere field on sphereGrid().
std::vector<Mesh> sphereLevels(double delta) { return polygonize(sphereField, sphereGrid(), {0.0, delta}).meshes; }

double sphereShellVolume(double delta) { return 4.0 / 3.0 * kPi * (std::pow(kR, 3) - std::pow(kR - delta, 3)); }

/// The volume of the sphere shell R − δ ≤ |x| ≤ R inside the cylinder ρ ≤ r below the centre.
double holeInShell(double delta, double r) {
  const auto cap = [r](double radius) { return std::pow(radius, 3) - std::pow(radius * radius - r * r, 1.5); };
  return 2.0 * kPi / 3.0 * (cap(kR) - cap(kR - delta));
}

}  // namespace

TEST_SUITE("surfaces") {

TEST_CASE("shell: a sphere's zero level and reversed inner offset form one closed solid of the exact volume") {
  const double delta = 0.1;
  const std::vector<Mesh> levels = sphereLevels(delta);
  ShellOptions o;
  o.offset = delta;
  const ShellResult s = buildShell(levels[0], levels[1], o);
  const ShellReport& r = s.report;
  CHECK(r.offset == delta);
  CHECK(r.topology.watertight());
  CHECK(r.topology.manifold());
  CHECK(r.topology.oriented());
  CHECK(r.topology.components == 2);
  CHECK(r.topology.faces == static_cast<std::size_t>(levels[0].faces.rows() + levels[1].faces.rows()));
  CHECK(r.volume > 0.0);
  CHECK(r.volume == doctest::Approx(r.zeroMinusOffsetVolume()).epsilon(1e-12));
  CHECK(std::abs(r.relativeDifference()) < 1e-12);
  CHECK(r.volume == doctest::Approx(sphereShellVolume(delta)).epsilon(2e-3));
  CHECK(r.offsetVolume == doctest::Approx(4.0 / 3.0 * kPi * std::pow(kR - delta, 3)).epsilon(2e-3));
  CHECK(r.intersectionsChecked);
  CHECK(r.intersectionsComplete);
  CHECK(r.intersections == 0);
  CHECK_FALSE(r.intersects());
  CHECK(r.drainHoles.empty());
  CHECK(r.valid());
  // The offset's faces come last, reversed and shifted by the zero mesh's vertex count.
  const Eigen::Index nz = levels[0].vertices.rows(), last = s.mesh.faces.rows() - 1;
  const Eigen::Index lastOffset = levels[1].faces.rows() - 1;
  CHECK(s.mesh.faces(last, 0) == levels[1].faces(lastOffset, 0) + nz);
  CHECK(s.mesh.faces(last, 1) == levels[1].faces(lastOffset, 2) + nz);
  CHECK(s.mesh.faces(last, 2) == levels[1].faces(lastOffset, 1) + nz);
  CHECK(signedVolume(levels[1]) > 0.0);  // the offset mesh alone is outward; in the shell it faces the cavity
}

TEST_CASE("shell: an inner surface that crosses the outer one is flagged, and bad input is refused") {
  const Mesh outer = testing::icosphere(3, 1.0);
  const Mesh crossing = testing::icosphere(3, 0.8, Eigen::RowVector3d(0.5, 0.0, 0.0));
  ShellOptions o;
  o.offset = 0.2;
  const ShellReport r = buildShell(outer, crossing, o).report;
  CHECK(r.intersectionsChecked);
  CHECK(r.intersects());
  CHECK(r.intersections > 0);
  CHECK_FALSE(r.valid());
  CHECK(r.topology.watertight());  // closed and oriented, yet not a solid
  o.checkIntersections = false;
  const ShellReport unchecked = buildShell(outer, crossing, o).report;
  CHECK_FALSE(unchecked.intersectionsChecked);
  CHECK_FALSE(unchecked.intersects());

  const Mesh inner = testing::icosphere(3, 0.8);
  for (const double bad : {0.0, -0.1, std::nan("")}) {
    ShellOptions b;
    b.offset = bad;
    CHECK_THROWS_WITH_AS(buildShell(outer, inner, b), doctest::Contains("inward offset"), InvalidArgument);
  }
  ShellOptions holes;
  holes.offset = 0.2;
  holes.drainHoles.push_back({Eigen::Vector3d::Zero(), 0.1});
  CHECK_THROWS_AS(buildShell(outer, inner, holes), InvalidArgument);  // holes are cut in the field

  ShellOptions parsed;
  parseDrainHoleSpec("0.1,-0.2,0.3,0.05", parsed);
  REQUIRE(parsed.drainHoles.size() == 1);
  CHECK(parsed.drainHoles[0].point.isApprox(Eigen::Vector3d(0.1, -0.2, 0.3)));
  CHECK(parsed.drainHoles[0].radius == 0.05);
  CHECK_FALSE(parsed.autoDrainHoles);
  parseDrainHoleSpec("auto", parsed);
  CHECK(parsed.autoDrainHoles);
  CHECK(parsed.autoDrainRadius == 0.0);
  parseDrainHoleSpec("auto,0.02", parsed);
  CHECK(parsed.autoDrainRadius == 0.02);
  CHECK(parsed.drained());
  for (const char* bad : {"", "1,2,3", "1,2,3,0", "1,2,3,-1", "1,2,x,1", "1,2,3,4,5", "auto,0", "auto,1,2", "a,b"}) {
    CAPTURE(bad);
    ShellOptions b;
    CHECK_THROWS_WITH_AS(parseDrainHoleSpec(bad, b), doctest::Contains("--drain-hole"), InvalidArgument);
  }
  CHECK(parseDrainHoles({"1,2,3,0.5", "0,0,0,1"}).size() == 2);
  CHECK_THROWS_WITH_AS(parseDrainHoles({"1,2,3,0.5", "auto"}), doctest::Contains("--drain-hole"), InvalidArgument);
}

TEST_CASE("shell: a drain hole's distance is exact and the drained function's derivatives are its pieces'") {
  const DrainHole h{Eigen::Vector3d(0.2, -0.1, 0.3), 0.1};
  const auto at = [&](double rho, double z) {  // a point at distance rho from the axis, at height z
    return Eigen::Vector3d(0.2 + rho * 0.6, -0.1 + rho * 0.8, z);
  };
  CHECK(drainHoleDistance(h, at(0.3, 0.0)) == doctest::Approx(0.2));               // beside the side
  CHECK(drainHoleDistance(h, at(0.05, 0.5)) == doctest::Approx(0.2));              // above the top disc
  CHECK(drainHoleDistance(h, at(0.4, 0.7)) == doctest::Approx(0.5));               // off the rim (0.3, 0.4)
  CHECK(drainHoleDistance(h, at(0.08, -5.0)) == doctest::Approx(-0.02));           // inside, nearest the side
  CHECK(drainHoleDistance(h, at(0.0, 0.27)) == doctest::Approx(-0.03));            // inside, nearest the top
  CHECK(drainHoleDistance(h, at(0.0, -100.0)) == doctest::Approx(-0.1));           // no bottom end

  // f = 10 (flat) and δ = 20: only the hole's piece is below 10 near it.
  const std::vector<DrainHole> holes{h};
  const auto samples = [&](const Points& q, FieldDerivatives d) {
    FieldSamples f;
    f.values = Eigen::VectorXd::Constant(q.rows(), 10.0);
    if (d != FieldDerivatives::None) f.gradients = Points::Zero(q.rows(), 3);
    if (d == FieldDerivatives::Hessian) f.hessians.setZero(q.rows(), 6);
    return drainedShellSamples(q, f, 20.0, holes);
  };
  const double e = 1e-5;
  for (const Eigen::Vector3d& x : {at(0.3, 0.0), at(0.05, 0.5), at(0.4, 0.7), at(0.08, -1.0), at(0.01, 0.28)}) {
    CAPTURE(x.transpose());
    Points q(1, 3);
    q.row(0) = x.transpose();
    const FieldSamples s = samples(q, FieldDerivatives::Hessian);
    CHECK(s.values[0] == doctest::Approx(drainHoleDistance(h, x)));
    Points p(6, 3);
    for (int a = 0; a < 3; ++a) {
      p.row(2 * a) = (x + e * Eigen::Vector3d::Unit(a)).transpose();
      p.row(2 * a + 1) = (x - e * Eigen::Vector3d::Unit(a)).transpose();
    }
    const FieldSamples n = samples(p, FieldDerivatives::Gradient);
    for (int a = 0; a < 3; ++a) {
      CHECK(s.gradients(0, a) == doctest::Approx((n.values[2 * a] - n.values[2 * a + 1]) / (2 * e)).epsilon(1e-6));
      // Row a of the Hessian from the gradients' differences; stored xx, xy, xz, yy, yz, zz.
      const int index[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
      for (int b = 0; b < 3; ++b) {
        const double fd = (n.gradients(2 * a, b) - n.gradients(2 * a + 1, b)) / (2 * e);
        CHECK(s.hessians(0, index[a][b]) == doctest::Approx(fd).epsilon(1e-4));
      }
    }
  }
  // The inner surface's piece δ − f has the gradient −∇f.
  FieldSamples f;
  f.values = Eigen::VectorXd::Constant(1, 0.08);
  f.gradients = Points(1, 3);
  f.gradients << 0.0, 0.0, -1.0;
  Points q(1, 3);
  q << 0.0, 0.0, 0.42;
  const FieldSamples g = drainedShellSamples(q, f, 0.1, {});
  CHECK(g.values[0] == doctest::Approx(0.02));
  CHECK(g.gradients(0, 2) == doctest::Approx(1.0));
  CHECK(g.hessians.rows() == 0);
  CHECK_THROWS_AS(drainedShellSamples(Points(2, 3), f, 0.1, {}), InvalidArgument);
}

TEST_CASE("shell: a drain hole through a sphere shell gives one closed genus-0 solid minus the hole's volume") {
  const double delta = 0.1, r = 0.1;
  const std::vector<Mesh> levels = sphereLevels(delta);
  ShellOptions o;
  o.offset = delta;
  const ShellReport whole = buildShell(levels[0], levels[1], o).report;
  o.drainHoles.push_back({Eigen::Vector3d::Zero(), r});  // from the centre straight down
  const ShellResult s = drainShell(sphereField, sphereGrid(), levels[0], levels[1], o);
  const ShellReport& d = s.report;
  CHECK(d.topology.watertight());
  CHECK(d.topology.manifold());
  CHECK(d.topology.oriented());
  CHECK(d.topology.components == 1);
  CHECK(d.topology.eulerCharacteristic == 2);  // the two spheres joined by the hole's wall: genus 0
  CHECK(d.intersections == 0);
  CHECK(d.valid());
  REQUIRE(d.drainHoles.size() == 1);
  CHECK(d.zeroMinusOffsetVolume() == doctest::Approx(whole.volume).epsilon(1e-12));
  const double removed = whole.volume - d.volume, exact = holeInShell(delta, r);
  MESSAGE("drained sphere shell: volume " << d.volume << ", removed " << removed << " (exact " << exact << ", pi r^2 delta "
                                          << kPi * r * r * delta << "), relative difference " << d.relativeDifference());
  CHECK(removed == doctest::Approx(exact).epsilon(0.05));
  CHECK(d.relativeDifference() == doctest::Approx(-exact / whole.volume).epsilon(0.05));
  // Every vertex on the hole's wall or the shell's surfaces: none inside the hole in the bottom wall.
  for (Eigen::Index v = 0; v < s.mesh.vertices.rows(); ++v) {
    const Eigen::Vector3d x = s.mesh.vertices.row(v).transpose();
    if (x.z() < 0.0) CHECK(std::hypot(x.x(), x.y()) > r - 0.02);
  }
  // Without holes drainShell meshes {min(f, δ − f) = 0}: the same shell as the joined meshes.
  ShellOptions plain;
  plain.offset = delta;
  const ShellReport g = drainShell(sphereField, sphereGrid(), levels[0], levels[1], plain).report;
  CHECK(g.topology.components == 2);
  CHECK(g.volume == doctest::Approx(whole.volume).epsilon(1e-4));

  // Automatic: one cavity, its hole on the vertical through the cavity's lowest point.
  ShellOptions automatic;
  automatic.offset = delta;
  automatic.autoDrainHoles = true;
  automatic.autoDrainRadius = r;
  const ShellReport a = drainShell(sphereField, sphereGrid(), levels[0], levels[1], automatic).report;
  REQUIRE(a.drainHoles.size() == 1);
  CHECK(std::hypot(a.drainHoles[0].point.x(), a.drainHoles[0].point.y()) < 0.03);
  CHECK(a.drainHoles[0].point.z() == doctest::Approx(-(kR - delta) + r).epsilon(0.02));
  CHECK(a.drainHoles[0].radius == r);
  CHECK(a.topology.components == 1);
  CHECK(a.topology.watertight());
  CHECK(a.volume < whole.volume);
  const std::vector<DrainHole> none = autoDrainHoles(Mesh{}, 0.1);
  CHECK(none.empty());
  CHECK_THROWS_AS(autoDrainHoles(levels[1], 0.0), InvalidArgument);
  ShellOptions badHole = plain;
  badHole.drainHoles.push_back({Eigen::Vector3d::Zero(), -1.0});
  CHECK_THROWS_WITH_AS(drainShell(sphereField, sphereGrid(), levels[0], levels[1], badHole),
                       doctest::Contains("--drain-hole"), InvalidArgument);
}

}  // TEST_SUITE
