// The bilateral point filter (docs/method.md §9): the device kernel against its C++ twin, denoising of an
// analytic noisy sphere (RMS radial error down, only a small radial bias), the shared noisy fandisk,
// parameter rules and overrides, and bad input.
#include <doctest/doctest.h>

#include <cmath>
#include <string>
#include <vector>

#include "data.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/preprocess.hpp"
#include "preprocess/preprocess_test_util.hpp"
#include "support/recording_interrupter.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

double maxDifference(const Points& a, const Points& b) { return (a - b).rowwise().norm().maxCoeff(); }

}  // namespace

TEST_SUITE("preprocess") {

TEST_CASE("bilateral: device kernel agrees with the reference twin") {
  DUPLEXFIT_OPENCL_DEVICE(dev);
  // 20000 and 1001 points: neither is a multiple of the work-group size.
  for (int n : {20000, 1001}) {
    CAPTURE(n);
    const PointSet noisy = testing::noisySphere(n, 0.5, 0.005);
    BilateralOptions o;
    const BilateralResult refResult = bilateralFilter(Device::reference(), noisy, o);
    const PointSet& ref = refResult.points;
    const BilateralReport& rr = refResult.report;
    const BilateralResult gotResult = bilateralFilter(dev, noisy, o);
    const PointSet& got = gotResult.points;
    const BilateralReport& rd = gotResult.report;
    CHECK(rd.device == dev.info().spec);
    CHECK(rd.sigmaSpatial == rr.sigmaSpatial);
    CHECK(rd.radius == rr.radius);
    const double diff = maxDifference(ref.positions(), got.positions());
    MESSAGE("float: max |device - reference| = " << diff << " (max displacement " << rr.maxDisplacement << ")");
    CHECK(diff <= 1e-6);
    CHECK(rr.maxDisplacement > 1e-3);  // the comparison is not trivial
    CHECK(maxDifference(got.normals(), noisy.normals()) < 1e-15);
    if (dev.supportsDouble()) {
      o.precision = Precision::Double;
      const PointSet refD = bilateralFilter(Device::reference(), noisy, o).points;
      const PointSet gotD = bilateralFilter(dev, noisy, o).points;
      CHECK(maxDifference(refD.positions(), gotD.positions()) <= 1e-12);
      CHECK(maxDifference(refD.positions(), ref.positions()) <= 1e-6);  // float vs double
    }
  }
}

TEST_CASE("bilateral: noisy sphere, RMS radial error down, small radial bias") {
  const double radius = 0.5, noise = 0.005;
  const PointSet noisy = testing::noisySphere(20000, radius, noise);
  const testing::RadialError before = testing::radialError(noisy.positions(), radius);
  const BilateralResult outResult = bilateralFilter(Device::reference(), noisy, BilateralOptions{});
  const PointSet& out = outResult.points;
  const BilateralReport& rep = outResult.report;
  const testing::RadialError after = testing::radialError(out.positions(), radius);
  const double spread = std::sqrt(after.rms * after.rms - after.mean * after.mean);
  MESSAGE("rms " << before.rms << " -> " << after.rms << " (bias " << after.mean << ", spread " << spread
                 << "); sigma_s " << rep.sigmaSpatial << ", radius " << rep.radius << ", sigma_M " << rep.areaSigma
                 << " (M " << rep.levels << "), " << rep.meanNeighbors << " neighbours");
  CHECK(after.rms < 0.4 * before.rms);
  CHECK(spread < 0.25 * noise);
  // Tangent planes of a convex surface lie outside it, so the projections K_q(p) move points outward by
  // about E‖q − p‖²/(2R): a bias of a fraction of the noise, not a shrinkage.
  CHECK(std::abs(after.mean) < 0.005 * radius);
  CHECK(std::abs(after.mean) < 0.4 * noise);
  // The spec's rules: σ_ψ = σ_ζ = 4 R_ave, radius 2σ_ψ, σ = σ_M of the fit's hierarchy.
  CHECK(rep.sigmaSpatial == doctest::Approx(4 * rep.rAve));
  CHECK(rep.sigmaRange == rep.sigmaSpatial);
  CHECK(rep.radius == doctest::Approx(2 * rep.sigmaSpatial));
  const FitScales scales = fitScales(noisy.positions());
  CHECK(rep.levels == scales.levels);
  CHECK(rep.areaSigma == doctest::Approx(0.75 * scales.diagonal / std::pow(2.0, rep.levels - 1)));
  CHECK(rep.levels >= 5);
  CHECK(rep.points == noisy.size());
  CHECK(rep.moved == noisy.size());
  CHECK(rep.iterations == 1);
  CHECK(rep.meanNeighbors > 20);
  CHECK(rep.isolated == 0);
  CHECK(rep.maxDisplacement >= rep.meanDisplacement);
  CHECK(rep.meanDisplacement > 0.5 * noise);
  CHECK(maxDifference(out.normals(), noisy.normals()) < 1e-15);

  // More passes keep smoothing the spread while the outward bias grows.
  BilateralOptions o;
  o.iterations = 2;
  const BilateralResult out2Result = bilateralFilter(Device::reference(), noisy, o);
  const PointSet& out2 = out2Result.points;
  const BilateralReport& rep2 = out2Result.report;
  const testing::RadialError after2 = testing::radialError(out2.positions(), radius);
  CHECK(rep2.iterations == 2);
  CHECK(after2.mean > after.mean);
  CHECK(std::sqrt(after2.rms * after2.rms - after2.mean * after2.mean) < spread);
  CHECK(rep2.sigmaSpatial == rep.sigmaSpatial);  // chosen once, from the input
}

TEST_CASE("bilateral: shared noisy fandisk moves toward the clean surface") {
  DUPLEXFIT_SHARED_DATA_DIR(data);
  const PointSet clean = readPointCloud(data + "/clouds/fandisk_50k.ply");
  const PointSet noisy = readPointCloud(data + "/clouds/fandisk_50k_noise0.5pct.ply");
  REQUIRE(clean.size() == noisy.size());
  // The noisy cloud is the clean one plus noise, point for point, with the clean normals: the error along
  // the true normal of the clean point measures the distance to the surface (away from edges).
  const std::vector<char> mask = testing::smoothMask(clean);
  const PointSet out = bilateralFilter(Device::reference(), noisy, BilateralOptions{}).points;
  double before = 0, after = 0;
  std::size_t m = 0;
  for (std::size_t i = 0; i < clean.size(); ++i) {
    if (!mask[i]) continue;
    const auto ii = static_cast<Eigen::Index>(i);
    const double b = (noisy.positions().row(ii) - clean.positions().row(ii)).dot(clean.normals().row(ii));
    const double a = (out.positions().row(ii) - clean.positions().row(ii)).dot(clean.normals().row(ii));
    before += b * b;
    after += a * a;
    ++m;
  }
  before = std::sqrt(before / static_cast<double>(m));
  after = std::sqrt(after / static_cast<double>(m));
  MESSAGE("fandisk: rms normal error " << before << " -> " << after << " over " << m << " smooth points");
  CHECK(after < 0.5 * before);
}

TEST_CASE("bilateral: overrides, zero normals and normal re-estimation") {
  const PointSet noisy = testing::noisySphere(3000, 0.5, 0.005);
  const Device ref = Device::reference();
  SUBCASE("explicit parameters are used as given") {
    BilateralOptions o;
    o.sigmaSpatial = 0.05;
    o.sigmaRange = 0.02;
    o.radius = 0.08;
    o.areaSigma = 0.04;
    o.symmetricRange = true;
    const BilateralReport rep = bilateralFilter(ref, noisy, o).report;
    CHECK(rep.sigmaSpatial == 0.05);
    CHECK(rep.sigmaRange == 0.02);
    CHECK(rep.radius == 0.08);
    CHECK(rep.areaSigma == 0.04);
    CHECK(rep.levels == 0);
    CHECK(rep.symmetricRange);
  }
  SUBCASE("a tiny radius leaves every point alone") {
    BilateralOptions o;
    o.radius = 1e-6;
    const BilateralResult outResult = bilateralFilter(ref, noisy, o);
    const PointSet& out = outResult.points;
    const BilateralReport& rep = outResult.report;
    CHECK(rep.isolated == noisy.size());
    CHECK(rep.moved == 0);
    CHECK(out.positions() == noisy.positions());
  }
  SUBCASE("zero normals: every projection is the point itself") {
    const PointSet flat(noisy.positions(), Points::Zero(noisy.positions().rows(), 3));
    const BilateralResult outResult = bilateralFilter(ref, flat, BilateralOptions{});
    const PointSet& out = outResult.points;
    const BilateralReport& rep = outResult.report;
    CHECK(maxDifference(out.positions(), flat.positions()) < 1e-12);
    CHECK(rep.moved == 0);
  }
  SUBCASE("re-estimated normals follow the surface and keep the input's sign") {
    BilateralOptions o;
    o.reestimateNormals = true;
    const BilateralResult outResult = bilateralFilter(ref, noisy, o);
    const PointSet& out = outResult.points;
    const BilateralReport& rep = outResult.report;
    CHECK(rep.normalsReestimated);
    double worst = 0;
    for (Eigen::Index i = 0; i < out.positions().rows(); ++i) {
      const Eigen::RowVector3d truth = out.positions().row(i).normalized();
      worst = std::max(worst, testing::angleDeg(out.normals().row(i), truth));
    }
    MESSAGE("re-estimated normals: worst angle " << worst << " deg");
    CHECK(worst < 10.0);
  }
}

TEST_CASE("bilateral: bad input") {
  const Device ref = Device::reference();
  const PointSet noisy = testing::noisySphere(200, 0.5, 0.005);
  BilateralOptions o;
  o.sigmaSpatial = -1;
  CHECK_THROWS_AS(bilateralFilter(ref, noisy, o).points, InvalidArgument);
  o = {};
  o.radius = std::nan("");
  CHECK_THROWS_AS(bilateralFilter(ref, noisy, o).points, InvalidArgument);
  o = {};
  o.iterations = 0;
  CHECK_THROWS_WITH_AS(bilateralFilter(ref, noisy, o).points, doctest::Contains("iterations"), InvalidArgument);
  const PointSet one(Points::Zero(1, 3), Points::Zero(1, 3));
  CHECK_THROWS_WITH_AS(bilateralFilter(ref, one, {}).points, doctest::Contains("at least 2 points"), InvalidArgument);
  const PointSet same(Points::Ones(5, 3), Points::Zero(5, 3));
  CHECK_THROWS_WITH_AS(bilateralFilter(ref, same, {}).points, doctest::Contains("coincide"), InvalidArgument);
}

TEST_CASE("bilateral and normals: the interrupter is polled and cancels") {
  const PointSet noisy = testing::noisySphere(3000, 0.5, 0.002);
  BilateralOptions o;
  o.iterations = 3;
  testing::RecordingInterrupter recorder;
  const BilateralResult done = bilateralFilter(Device::reference(), noisy, o, &recorder);
  CHECK(done.report.iterations == 3);
  CHECK(recorder.percents == std::vector<int>{0, 33, 66});
  testing::RecordingInterrupter canceller;
  canceller.stopWhen = [](const testing::RecordingInterrupter& i) { return i.percents.size() == 2; };
  CHECK_THROWS_WITH_AS(bilateralFilter(Device::reference(), noisy, o, &canceller), doctest::Contains("pass 2"),
                       Cancelled);
  testing::RecordingInterrupter normals;
  normals.stopWhen = [](const testing::RecordingInterrupter& i) { return i.percents.back() == 50; };
  CHECK_THROWS_WITH_AS(estimateNormals(Device::reference(), noisy.positions(), NormalOptions{}, &normals),
                       doctest::Contains("orientation"), Cancelled);
  CHECK(normals.percents == std::vector<int>{0, 50});
}

}  // TEST_SUITE
