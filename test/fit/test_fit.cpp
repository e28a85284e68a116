// Duplex fitting on generated analytic shapes: the zero and δ level sets sit where the exact geometry
// says, the OpenCL path agrees with the reference path, and bad options are clear errors.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>
#include <string>

#include "support/recording_interrupter.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/wendland.hpp"
#include "fit/fit_detail.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

PointSet sphereCloud(int n, double radius) {
  Points normals;
  Points p = testing::fibonacciSphere(n, radius, &normals);
  return PointSet(std::move(p), std::move(normals));
}

// max |f − expected| over points on a sphere of the given radius.
double sphereError(const ImplicitField& f, const Device& d, double radius, double expected) {
  const Points q = testing::fibonacciSphere(1500, radius);
  const Eigen::VectorXd v = f.evaluate(d, q).values;
  return (v.array() - expected).abs().maxCoeff();
}

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("fit: a sphere with an inward offset puts f = 0 on the surface and f = δ on the offset sphere") {
    const PointSet cloud = sphereCloud(4000, 0.5);
    FitOptions options;
    options.offsets = {0.1};
    std::vector<Device> devices{Device::reference()};
    if (const Device* d = testing::openclTestDevice()) devices.push_back(*d);
    std::vector<Eigen::VectorXd> samples;
    const Points probe = testing::fibonacciSphere(500, 0.45);
    for (const Device& d : devices) {
      CAPTURE(d.info().spec);
      const FitResult r = fit(d, cloud, options);
      CHECK(r.report.levels >= 4);
      CHECK(r.report.levels <= 7);
      // fitScales (public: the bilateral filter's σ) states the fit's own supports, in input units.
      const FitScales scales = fitScales(cloud.positions(), options.alpha);
      CHECK(scales.levels == r.report.levels);
      CHECK(scales.sigma1 == doctest::Approx(r.report.sigma1).epsilon(1e-9));
      CHECK(scales.sigma0 == doctest::Approx(r.report.sigma0).epsilon(1e-9));
      CHECK(scales.sigmaFinest == doctest::Approx(r.report.sigma1 / std::pow(2.0, r.report.levels - 1)).epsilon(1e-9));
      CHECK(r.report.offSurfaceSide == OffSurfaceSide::Outside);
      for (const LevelReport& l : r.report.levelReports) {
        CHECK(l.solve.converged);
        CHECK(l.offsetKept[0] == l.offsetCandidates[0]);  // exact normals on a sphere: all valid (§3.1)
      }
      CHECK(r.report.e0 <= 1e-4);
      CHECK(r.report.eDelta[0] <= 1e-4);
      // E_0 (taken from the final residual where possible) equals max |f| over the input points, up to
      // the float evaluation error of the coarser levels in that residual.
      const double direct = r.field.evaluate(Device::reference(), cloud.positions(), FieldDerivatives::None,
                                             Precision::Double).values.cwiseAbs().maxCoeff();
      CHECK(std::abs(r.report.e0 - direct) <= 1e-6);
      CHECK(sphereError(r.field, d, 0.5, 0.0) <= 1e-3);
      CHECK(sphereError(r.field, d, 0.4, 0.1) <= 1e-3);  // within 1% of δ on the exact offset surface
      // Sign and level sets elsewhere: outside negative, inside above δ, far away −1.
      CHECK(r.field.evaluate(d, testing::fibonacciSphere(200, 0.6)).values.maxCoeff() < 0.0);
      CHECK(r.field.evaluate(d, testing::fibonacciSphere(200, 0.3)).values.minCoeff() > 0.1);
      CHECK(r.field.value(Eigen::Vector3d(5, 5, 5)) == doctest::Approx(-1.0 / r.field.normalization().scale));
      samples.push_back(r.field.evaluate(Device::reference(), probe, FieldDerivatives::None, Precision::Double).values);
    }
    if (samples.size() == 2) CHECK((samples[0] - samples[1]).cwiseAbs().maxCoeff() <= 1e-4);
  }

  TEST_CASE("fit: the cloud's order does not change the field (the fit works in the points' Morton order)") {
    // A torus (sign anchors in its hole) in its own order and in a shuffled one: the same levels, centres
    // and weights bit for bit, and the same E_0 and E_δ.
    Points normals;
    const Points p = testing::sampledTorus(4000, 0.3, 0.1, &normals);
    std::vector<Eigen::Index> order(static_cast<std::size_t>(p.rows()));
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<Eigen::Index>(i);
    std::uint64_t state = 12345;  // a fixed permutation (Fisher-Yates on a 64-bit LCG)
    for (std::size_t i = order.size() - 1; i > 0; --i) {
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      std::swap(order[i], order[static_cast<std::size_t>((state >> 33) % (i + 1))]);
    }
    Points ps(p.rows(), 3), ns(p.rows(), 3);
    for (Eigen::Index r = 0; r < p.rows(); ++r) {
      ps.row(r) = p.row(order[static_cast<std::size_t>(r)]);
      ns.row(r) = normals.row(order[static_cast<std::size_t>(r)]);
    }
    REQUIRE(ps != p);
    FitOptions o;
    o.offsets = {0.04};
    const Device d = testing::openclTestDevice() != nullptr ? *testing::openclTestDevice() : Device::reference();
    const FitResult a = fit(d, PointSet(p, normals), o);
    const FitResult b = fit(d, PointSet(ps, ns), o);
    REQUIRE(a.field.levels().size() == b.field.levels().size());
    for (std::size_t k = 0; k < a.field.levels().size(); ++k) {
      CAPTURE(k);
      CHECK(a.field.levels()[k].sigma == b.field.levels()[k].sigma);
      CHECK(a.field.levels()[k].centres == b.field.levels()[k].centres);
      CHECK(a.field.levels()[k].weights == b.field.levels()[k].weights);
    }
    CHECK(a.report.e0 == b.report.e0);
    CHECK(a.report.eDelta == b.report.eDelta);
    CHECK(a.report.e0 <= 1e-4);
  }

  TEST_CASE("fit: an outward offset and several offsets in one field are each right") {
    const PointSet cloud = sphereCloud(3000, 0.5);
    const Device d = testing::openclTestDevice() != nullptr ? *testing::openclTestDevice() : Device::reference();
    FitOptions out;
    out.offsets = {-0.05};
    const FitResult r = fit(d, cloud, out);
    CHECK(r.report.offSurfaceSide == OffSurfaceSide::Inside);
    CHECK(sphereError(r.field, d, 0.55, -0.05) <= 5e-4);
    CHECK(sphereError(r.field, d, 0.5, 0.0) <= 5e-4);

    FitOptions both;
    both.offsets = {0.1, 0.05, -0.05};
    const FitResult m = fit(d, cloud, both);
    CHECK(m.report.offSurfaceSide == OffSurfaceSide::None);
    CHECK(m.report.offsets.size() == 3);
    CHECK(sphereError(m.field, d, 0.4, 0.1) <= 1e-3);
    CHECK(sphereError(m.field, d, 0.45, 0.05) <= 5e-4);
    CHECK(sphereError(m.field, d, 0.55, -0.05) <= 5e-4);
    CHECK(sphereError(m.field, d, 0.5, 0.0) <= 5e-4);
  }

  TEST_CASE("fit --separate: one independent field per surface, each 0-level on its own sphere") {
    DUPLEXFIT_OPENCL_DEVICE(d);
    const PointSet cloud = sphereCloud(3000, 0.5);
    FitOptions options;
    options.offsets = {0.1, -0.05};
    const SeparateFitResult r = fitSeparate(d, cloud, options);
    REQUIRE(r.offsets.size() == 2);
    REQUIRE(r.offsetReports.size() == 2);
    CHECK(r.offsetDeltas == std::vector<double>{0.1, -0.05});
    CHECK(r.offsetPoints == std::vector<std::size_t>{3000, 3000});  // exact normals: every offset point valid
    // Every field is a plain surface fit: no offsets inside it, off-surface points on both sides.
    for (const FitReport* rep : {&r.zeroReport, &r.offsetReports[0], &r.offsetReports[1]}) {
      CHECK(rep->offsets.empty());
      CHECK(rep->offSurfaceSide == OffSurfaceSide::Both);
      CHECK(rep->e0 <= 1e-4);
    }
    CHECK(r.zero.offsets().empty());
    CHECK(sphereError(r.zero, d, 0.5, 0.0) <= 1e-3);
    CHECK(sphereError(r.offsets[0], d, 0.4, 0.0) <= 1e-3);   // inward δ = 0.1: the sphere of radius 0.4
    CHECK(sphereError(r.offsets[1], d, 0.55, 0.0) <= 1e-3);  // outward δ = 0.05: radius 0.55
    // Independent: the offset field does not vanish on the input surface, the zero field not on the offset.
    CHECK(r.offsets[0].evaluate(d, cloud.positions()).values.cwiseAbs().minCoeff() > 0.01);
    CHECK(r.zero.evaluate(d, testing::fibonacciSphere(300, 0.4)).values.cwiseAbs().minCoeff() > 0.01);
    // The offset clouds sit at distance |δ| along the normals.
    const PointSet in = offsetPointCloud(cloud, 0.1);
    CHECK(in.positions().rowwise().norm().maxCoeff() == doctest::Approx(0.4).epsilon(1e-9));
    CHECK(in.positions().rowwise().norm().minCoeff() == doctest::Approx(0.4).epsilon(1e-9));
    CHECK_THROWS_AS(offsetPointCloud(cloud, 0.0), InvalidArgument);
    CHECK_THROWS_AS(offsetPointCloud(cloud, 0.9), InvalidArgument);  // deeper than the sphere: nothing valid
  }

  TEST_CASE("fit --side-test: offsets of flipped normals no longer plant a sheet outside the solid") {
    DUPLEXFIT_OPENCL_DEVICE(d);
    PointSet good = sphereCloud(3000, 0.5);
    // Flip the normals of the 6 points nearest to the +x pole: their inward offsets land outside.
    Points normals = good.normals();
    const Eigen::RowVector3d pole(0.5, 0.0, 0.0);
    std::vector<Eigen::Index> order(static_cast<std::size_t>(normals.rows()));
    for (Eigen::Index i = 0; i < normals.rows(); ++i) order[static_cast<std::size_t>(i)] = i;
    std::partial_sort(order.begin(), order.begin() + 6, order.end(), [&](Eigen::Index a, Eigen::Index b) {
      return (good.positions().row(a) - pole).norm() < (good.positions().row(b) - pole).norm();
    });
    for (int k = 0; k < 6; ++k) normals.row(order[static_cast<std::size_t>(k)]) *= -1.0;
    const PointSet bad(good.positions(), normals);
    FitOptions options;
    options.offsets = {0.1};
    const Eigen::Vector3d outside(0.6, 0.0, 0.0);  // where the flipped points' offsets go
    const FitResult plain = fit(d, bad, options);
    options.sideTest = true;
    const FitResult tested = fit(d, bad, options);
    MESSAGE("f at the flipped points' offsets: " << plain.field.value(outside) << " without, "
                                                  << tested.field.value(outside) << " with the side test");
    CHECK(plain.field.value(outside) > 0.0);   // a spurious solid outside the sphere
    CHECK(tested.field.value(outside) < 0.0);  // outside, as it should be
    CHECK(tested.report.levelReports.back().offsetKept[0] < 3000);
    CHECK(sphereError(tested.field, d, 0.4, 0.1) <= 0.01);
  }

  TEST_CASE("fit: relative offsets are fractions of the largest side") {
    const PointSet cloud = sphereCloud(1000, 2.0);  // largest side 4
    FitOptions o;
    o.offsets = {0.025};
    o.offsetsRelative = true;
    const FitResult r = fit(Device::reference(), cloud, o);
    REQUIRE(r.report.offsets.size() == 1);
    CHECK(r.report.offsets[0] == doctest::Approx(0.025 * cloud.bounds().sizes().maxCoeff()));
    CHECK(sphereError(r.field, Device::reference(), 2.0 - r.report.offsets[0], r.report.offsets[0]) <= 2e-3);
  }

  TEST_CASE("fit: a level's float solve that stalls at float's rounding is refined in double to the tolerance") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const Points centres = testing::fibonacciSphere(600, 0.5);
    const CsrMatrix a = assembleWendland(centres, 0.15);
    Eigen::VectorXd truth(centres.rows());
    for (Eigen::Index i = 0; i < truth.size(); ++i) truth[i] = std::sin(7.0 * centres(i, 0)) + centres(i, 2);
    const Eigen::VectorXd b = a.multiply(truth);
    FitOptions o;
    o.precision = Precision::Float;
    o.levelTolerance = 1e-10;  // far below what float's b − A x can show
    o.solver.relativeTolerance = 1e-14;
    o.preconditioner = PreconditionerKind::BlockJacobi;  // the same as the solve alone below
    // The float solve alone stalls above it ...
    const DeviceCsr m = DeviceCsr::upload(dev, a, Precision::Float);
    const DeviceVector db = DeviceVector::upload(dev, b, Precision::Float);
    DeviceVector x(dev, static_cast<std::size_t>(b.size()), Precision::Float);
    const BlockJacobiPreconditioner pre(dev, a, Precision::Float, o.blockSize);
    const SolveStats alone = solveCg(m, db, x, detail::levelSolverOptions(o, true), &pre);
    REQUIRE(alone.reason == StopReason::Stagnated);
    // ... the level solve refines it: the residual recomputed in double meets the tolerance.
    Eigen::VectorXd w;
    const SolveStats s = detail::solveLevelSystem(dev, a, b, o, true, w);
    CHECK(s.converged);
    CHECK(s.reason == StopReason::Converged);
    const double rmax = (b - a.multiply(w)).lpNorm<Eigen::Infinity>();
    MESSAGE("float alone: max residual " << alone.maxResidual << " after " << alone.iterations
                                         << " iterations; refined: " << rmax << " after " << s.iterations);
    CHECK(rmax <= 1e-10);
    CHECK(s.maxResidual == doctest::Approx(rmax).epsilon(1e-6));
    CHECK(s.iterations > alone.iterations);
  }

  TEST_CASE("fit: level matrices assembled on the device give the host's field bit for bit") {
    CHECK(parseAssemblyPlace("device") == AssemblyPlace::Device);
    CHECK(std::string(assemblyPlaceName(AssemblyPlace::Auto)) == "auto");
    CHECK_THROWS_WITH_AS(parseAssemblyPlace("gpu"), doctest::Contains("'gpu'"), InvalidArgument);
    const PointSet cloud = sphereCloud(3000, 0.5);
    FitOptions options;
    options.offsets = {0.1};
    // The reference device has no kernels: asked for the device, it assembles on the host.
    options.assembly = AssemblyPlace::Device;
    CHECK(fit(Device::reference(), cloud, options).report.assembly == "host");
    DUPLEXFIT_OPENCL_DEVICE(dev);
    if (!dev.supportsDouble()) DUPLEXFIT_SKIP("the OpenCL device has no double precision");
    // Auto: on a CPU device the host's cores assemble (faster there, docs/benchmarks.md).
    CHECK(detail::assemblesOnDevice(dev, FitOptions{}) == (dev.info().type != DeviceType::Cpu));
    options.assembly = AssemblyPlace::Host;
    const FitResult host = fit(dev, cloud, options);
    options.assembly = AssemblyPlace::Device;
    const FitResult device = fit(dev, cloud, options);
    CHECK(host.report.assembly == "host");
    CHECK(device.report.assembly == "device");
    REQUIRE(host.field.levels().size() == device.field.levels().size());
    for (std::size_t k = 0; k < host.field.levels().size(); ++k) {
      CAPTURE(k);
      CHECK(host.report.levelReports[k].nonZeros == device.report.levelReports[k].nonZeros);
      CHECK(host.report.levelReports[k].solve.iterations == device.report.levelReports[k].solve.iterations);
      CHECK(host.field.levels()[k].weights == device.field.levels()[k].weights);
    }
    CHECK(host.report.e0 == device.report.e0);
  }

  TEST_CASE("fit: bad input and options are clear errors") {
    const PointSet cloud = sphereCloud(500, 0.5);
    FitOptions zero;
    zero.offsets = {0.0};
    CHECK_THROWS_AS(fit(Device::reference(), cloud, zero), InvalidArgument);
    FitOptions huge;
    huge.offsets = {1.5};
    try {
      (void)fit(Device::reference(), cloud, huge);
      FAIL("expected InvalidArgument");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("largest side") != std::string::npos);
    }
    FitOptions eta;
    eta.validityTolerance = 1.5;
    CHECK_THROWS_AS(fit(Device::reference(), cloud, eta), InvalidArgument);
    CHECK_THROWS_AS(fit(Device::reference(), sphereCloud(7, 0.5), FitOptions{}), InvalidArgument);
  }

  TEST_CASE("fit: progress reports every stage and can cancel") {
    const PointSet cloud = sphereCloud(1000, 0.5);
    std::vector<FitStage> stages;
    FitOptions o;
    o.offsets = {0.1};
    testing::RecordingInterrupter recorder;
    const FitResult r = fit(Device::reference(), cloud, o, &recorder);
    for (const FitEvent& e : recorder.events) {
      if (stages.empty() || stages.back() != e.stage) stages.push_back(e.stage);
    }
    // One poll per event; the percents known within the levels (the fit's work, docs/architecture.md)
    // never decrease, start near 0 and reach 100 once the last solve converges.
    CHECK(recorder.percents.size() >= recorder.events.size());
    for (const FitEvent& e : recorder.events) {
      if (e.stage == FitStage::Solve && e.iteration > 0) CHECK(e.level >= 1);  // the solver's events carry the level
    }
    std::vector<int> known;
    for (const int p : recorder.percents) {
      if (p >= 0) known.push_back(p);
    }
    REQUIRE(known.size() >= 4);
    CHECK(std::is_sorted(known.begin(), known.end()));
    CHECK(known.front() <= 5);
    CHECK(known.back() == 100);
    CHECK(known.back() <= 100);
    // Hierarchy first, then per level constraints → residual (from level 2) → assembly → solve, errors last.
    REQUIRE(stages.size() >= 4);
    CHECK(stages.front() == FitStage::Hierarchy);
    CHECK(stages.back() == FitStage::Errors);
    CHECK(std::find(stages.begin(), stages.end(), FitStage::Constraints) != stages.end());
    CHECK(std::find(stages.begin(), stages.end(), FitStage::Assembly) != stages.end());
    CHECK(std::find(stages.begin(), stages.end(), FitStage::Solve) != stages.end());
    CHECK(std::string(fitStageName(FitStage::Solve)) == "solve");
    CHECK(std::string(offSurfaceSideName(r.report.offSurfaceSide)) == "outside");
    testing::RecordingInterrupter canceller;
    canceller.stopWhen = [](const testing::RecordingInterrupter& i) { return i.events.back().stage == FitStage::Assembly; };
    CHECK_THROWS_AS(fit(Device::reference(), cloud, o, &canceller), Cancelled);
    // A cancellation inside a CG solve stops the fit too.
    testing::RecordingInterrupter inSolve;
    FitOptions often = o;
    often.solver.progressInterval = 1;
    inSolve.stopWhen = [](const testing::RecordingInterrupter& i) { return i.events.back().iteration >= 2; };
    CHECK_THROWS_WITH_AS(fit(Device::reference(), cloud, often, &inSolve), doctest::Contains("solve"), Cancelled);
    // A cancellation inside the finest level's constraints (its neighbour searches poll the interrupter
    // between the stage's own events) stops the fit there: no later stage is reported.
    testing::RecordingInterrupter inConstraints;
    std::size_t constraintsPolls = 0;
    inConstraints.stopWhen = [&constraintsPolls](const testing::RecordingInterrupter& i) {
      const FitEvent& last = i.events.back();
      if (last.stage != FitStage::Constraints || last.level != last.levels) return false;
      return ++constraintsPolls >= 2;  // the stage's own poll, then the first poll inside a search
    };
    CHECK_THROWS_WITH_AS(fit(Device::reference(), cloud, o, &inConstraints), doctest::Contains("neighbour search"),
                         Cancelled);
    CHECK(constraintsPolls == 2);
    CHECK(inConstraints.events.back().stage == FitStage::Constraints);
  }
}
