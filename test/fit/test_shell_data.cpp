// The printable shell of fitted shared clouds (runPipeline with options.shell): sphere_10k at δ = 0.05
// against the exact shell volume (4/3)π(R³ − (R − δ)³), with a drain hole (one closed component, the hole's
// volume removed, g' < 0 on the hole's axis in the wall); maxplanck_12k at δ = 0.02, the target:
// the shell's volume within 0.5% of volume(zero) − volume(offset), also for the shell meshed directly as
// {min(f, δ − f) = 0}, and automatic holes. In the fit suite: these fit clouds (labels data and device).
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "data.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/pipeline.hpp"
#include "duplexfit/shell.hpp"
#include "json_report.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

constexpr double kPi = 3.14159265358979323846;

const Device& shellDevice() {
  static const Device ref = Device::reference();
  const Device* d = testing::openclTestDevice();
  return d != nullptr ? *d : ref;
}

/// The volume of the sphere shell R − δ ≤ |x − c| ≤ R inside the cylinder ρ ≤ r below the centre.
double holeInShell(double radius, double delta, double r) {
  const auto cap = [r](double s) { return std::pow(s, 3) - std::pow(s * s - r * r, 1.5); };
  return 2.0 * kPi / 3.0 * (cap(radius) - cap(radius - delta));
}

void checkSolid(const ShellReport& r) {
  CHECK(r.topology.watertight());
  CHECK(r.topology.manifold());
  CHECK(r.topology.oriented());
  CHECK(r.volume > 0.0);
  CHECK(r.intersectionsChecked);
  CHECK(r.intersectionsComplete);
  CHECK_FALSE(r.intersects());
  CHECK(r.valid());
}

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("shell data: sphere_10k at delta 0.05 is a closed shell of the exact volume; a drain hole cuts it") {
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    const testing::Json truth = testing::readJsonFile(dir + "/clouds/sphere_10k.json");
    const double radius = testing::jsonNumber(truth, "/radius");
    const Eigen::Vector3d centre(testing::jsonNumber(truth, "/center/0"), testing::jsonNumber(truth, "/center/1"),
                                 testing::jsonNumber(truth, "/center/2"));
    REQUIRE(radius > 0.0);
    const double delta = 0.05, r = 0.1;
    PipelineOptions o;
    o.fit.offsets = {delta};
    o.shell = true;
    o.shellOptions.drainHoles.push_back({centre, r});  // from the centre straight down through the bottom
    const PipelineResult result = runPipeline(shellDevice(), dir + "/clouds/sphere_10k.ply", o);
    REQUIRE(result.shell);
    REQUIRE(result.surfaces.size() == 2);
    CHECK(result.shell->surface == 1);

    ShellOptions plain;
    plain.offset = delta;
    const ShellResult whole = buildShell(result.surfaces[0].mesh, result.surfaces[1].mesh, plain);
    const ShellReport& w = whole.report;
    checkSolid(w);
    CHECK(w.topology.components == 2);
    const double exact = 4.0 / 3.0 * kPi * (std::pow(radius, 3) - std::pow(radius - delta, 3));
    MESSAGE("sphere_10k shell at delta 0.05: volume " << w.volume << ", exact " << exact << ", relative error "
                                                      << (w.volume - exact) / exact << "; zero - offset "
                                                      << w.zeroMinusOffsetVolume());
    CHECK(std::abs(w.volume - exact) <= 0.005 * exact);
    CHECK(std::abs(w.relativeDifference()) < 1e-9);

    const ShellReport& d = result.shell->report;
    checkSolid(d);
    CHECK(d.topology.components == 1);
    CHECK(d.topology.eulerCharacteristic == 2);
    REQUIRE(d.drainHoles.size() == 1);
    CHECK(d.zeroMinusOffsetVolume() == doctest::Approx(w.volume).epsilon(1e-12));
    const double removed = w.volume - d.volume, hole = holeInShell(radius, delta, r);
    MESSAGE("sphere_10k drained (r = 0.1 from the centre down): " << d.topology.faces << " faces, volume " << d.volume
                                                                  << ", removed " << removed << ", exact hole " << hole
                                                                  << " (pi r^2 delta " << kPi * r * r * delta << ")");
    CHECK(removed > 0.8 * hole);
    CHECK(removed < 1.2 * hole);

    // g' on the hole's axis in the bottom wall is < 0 (the hole); the field alone is inside the shell there.
    Points q(2, 3);
    q.row(0) = (centre - Eigen::Vector3d(0.0, 0.0, radius - delta / 2)).transpose();     // axis, in the wall
    q.row(1) = (centre + Eigen::Vector3d(radius - delta / 2, 0.0, 0.0)).transpose();     // wall, away from it
    const FieldSamples f = result.fields[0].evaluate(shellDevice(), q);
    const FieldSamples g = drainedShellSamples(q, f, delta, d.drainHoles);
    CHECK(f.values[0] > 0.0);
    CHECK(f.values[0] < delta);
    CHECK(g.values[0] < 0.0);
    CHECK(g.values[0] == doctest::Approx(-r).epsilon(1e-9));
    CHECK(g.values[1] > 0.0);
  }

  TEST_CASE("shell data: maxplanck_12k at delta 0.02: volume(shell) = volume(zero) - volume(offset) within 0.5%") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (the sphere_10k case runs the same shell and drain-hole code there)");
#endif
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    const double delta = 0.02;
    PipelineOptions o;
    o.fit.offsets = {delta};
    o.shell = true;
    o.shellOptions.autoDrainHoles = true;  // one hole of radius δ at the lowest point of each cavity
    const PipelineResult result = runPipeline(shellDevice(), dir + "/clouds/maxplanck_12k.ply", o);
    REQUIRE(result.shell);
    const Mesh& zero = result.surfaces[0].mesh;
    const Mesh& offset = result.surfaces[1].mesh;

    ShellOptions plain;
    plain.offset = delta;
    const ShellReport w = buildShell(zero, offset, plain).report;
    checkSolid(w);
    const double reference = w.zeroMinusOffsetVolume();
    CHECK(std::abs(w.volume - reference) <= 0.005 * reference);
    // Meshed directly as {min(f, δ − f) = 0} on the same grid (small cavities filled as the offset's clean-up).
    const FieldEvaluator evaluator(shellDevice(), result.fields[0]);
    const FieldSampler sampler = [&evaluator](const Points& q, Eigen::VectorXd& values) {
      values = evaluator.evaluate(q).values;
    };
    plain.minCavityFraction = o.selfCheck.minOffsetAreaFraction;
    const ShellReport direct = drainShell(sampler, result.report.grid, zero, offset, plain).report;
    checkSolid(direct);
    MESSAGE("maxplanck_12k shell at delta 0.02: zero " << w.zeroVolume << ", offset " << w.offsetVolume
                                                      << ", zero - offset " << reference << "; joined shell "
                                                      << w.volume << " (" << w.relativeDifference()
                                                      << "), min(f, delta - f) meshed " << direct.volume << " ("
                                                      << direct.relativeDifference() << "), " << w.topology.faces
                                                      << " faces");
    CHECK(std::abs(direct.relativeDifference()) <= 0.005);

    const ShellReport& d = result.shell->report;
    checkSolid(d);
    CHECK_FALSE(d.drainHoles.empty());
    // The holes take material away: less than the same g' meshed without holes (the joined shell's
    // meshes are projected onto their level sets, g' is meshed by marching tetrahedra alone).
    CHECK(d.volume < direct.volume);
    MESSAGE("maxplanck_12k drained (auto): " << d.drainHoles.size() << " hole(s), " << d.topology.components
                                             << " component(s), volume " << d.volume << " ("
                                             << d.relativeDifference() << ")");
  }
}
