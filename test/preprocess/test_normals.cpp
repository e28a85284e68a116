// Normal estimation: PCA accuracy and outward orientation on the shared clean clouds (their normals
// removed), several components, the device covariance sums against their C++ twin, and bad input.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "data.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/preprocess.hpp"
#include "preprocess/preprocess_device.hpp"
#include "preprocess/preprocess_test_util.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

struct NormalQuality {
  double meanAngleSmooth = 0.0;  ///< mean angle to the truth away from sharp edges (degrees)
  double maxAngleSmooth = 0.0;
  double outwardAll = 0.0;       ///< share of all points with n·n_true > 0
  double outwardSmooth = 0.0;
  std::size_t smooth = 0;
};

NormalQuality compare(const PointSet& est, const PointSet& truth) {
  const std::vector<char> mask = testing::smoothMask(truth);
  NormalQuality q;
  std::size_t outAll = 0, outSmooth = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const auto ii = static_cast<Eigen::Index>(i);
    const double a = testing::angleDeg(est.normals().row(ii), truth.normals().row(ii));
    outAll += a < 90.0 ? 1 : 0;
    if (!mask[i]) continue;
    ++q.smooth;
    outSmooth += a < 90.0 ? 1 : 0;
    q.meanAngleSmooth += a;
    q.maxAngleSmooth = std::max(q.maxAngleSmooth, a);
  }
  q.meanAngleSmooth /= static_cast<double>(std::max<std::size_t>(q.smooth, 1));
  q.outwardAll = static_cast<double>(outAll) / static_cast<double>(truth.size());
  q.outwardSmooth = static_cast<double>(outSmooth) / static_cast<double>(std::max<std::size_t>(q.smooth, 1));
  return q;
}

template <typename F>
void checkInvalid(F&& f, std::initializer_list<const char*> parts) {
  bool thrown = false;
  try {
    f();
  } catch (const InvalidArgument& e) {
    thrown = true;
    const std::string msg = e.what();
    INFO("message: " << msg);
    for (const char* p : parts) {
      INFO("expected: " << std::string(p));
      CHECK(msg.find(p) != std::string::npos);
    }
  }
  CHECK_MESSAGE(thrown, "no InvalidArgument thrown");
}

}  // namespace

TEST_SUITE("preprocess") {

TEST_CASE("normals: shared clean clouds, PCA accuracy and 100% outward") {
  DUPLEXFIT_SHARED_DATA_DIR(data);
  const Device ref = Device::reference();
  for (const std::string name : {"sphere_10k", "torus_10k", "bunny_35k", "fandisk_50k"}) {
    CAPTURE(name);
    const PointSet truth = readPointCloud(data + "/clouds/" + name + ".ply");
    const NormalResult estResult = estimateNormals(ref, truth.positions(), NormalOptions{});
    const PointSet& est = estResult.points;
    const NormalReport& rep = estResult.report;
    REQUIRE(est.size() == truth.size());
    CHECK(est.positions() == truth.positions());
    const NormalQuality q = compare(est, truth);
    MESSAGE(name << ": mean angle " << q.meanAngleSmooth << " deg (max " << q.maxAngleSmooth << ") over "
                 << q.smooth << " smooth points; outward " << 100 * q.outwardAll << "% all, " << 100 * q.outwardSmooth
                 << "% smooth; components " << rep.components << ", flipped comps " << rep.flippedComponents
                 << ", degenerate " << rep.degenerate << ", non-planar " << rep.nonPlanar << ", volume ratio "
                 << rep.minVolumeRatio << ", " << rep.seconds << " s (knn " << rep.neighborSeconds << ", pca "
                 << rep.pcaSeconds << ", orient " << rep.orientSeconds << ")");
    CHECK(q.meanAngleSmooth <= 5.0);
    CHECK(q.outwardSmooth == 1.0);
    CHECK(q.outwardAll == 1.0);
    CHECK(rep.components == 1);
    CHECK(rep.ambiguousComponents == 0);
    CHECK(rep.degenerate == 0);
  }
}

TEST_CASE("normals: device covariance sums agree with the reference twin") {
  DUPLEXFIT_OPENCL_DEVICE(dev);
  const PointSet noisy = testing::noisySphere(5001, 0.5, 0.002);  // not a multiple of the work-group size
  for (Precision p : {Precision::Float, Precision::Double}) {
    if (p == Precision::Double && !dev.supportsDouble()) continue;
    NormalOptions o;
    o.precision = p;
    const NormalResult refResult = estimateNormals(Device::reference(), noisy.positions(), o);
    const PointSet& ref = refResult.points;
    const NormalReport& rr = refResult.report;
    const NormalResult gotResult = estimateNormals(dev, noisy.positions(), o);
    const PointSet& got = gotResult.points;
    const NormalReport& rd = gotResult.report;
    CHECK(rd.device == dev.info().spec);
    CHECK(rr.device == Device::reference().info().spec);
    double worst = 0;
    for (Eigen::Index i = 0; i < ref.normals().rows(); ++i) {
      worst = std::max(worst, testing::angleDeg(ref.normals().row(i), got.normals().row(i)));
    }
    MESSAGE(std::string(precisionName(p)) << ": worst angle device vs reference " << worst << " deg");
    CHECK(worst < (p == Precision::Float ? 1e-2 : 1e-4));
  }
  // The raw kernel output against the twin, element by element.
  const Points& x = noisy.positions();
  const std::size_t n = static_cast<std::size_t>(x.rows()), k1 = 9;
  std::vector<double> pos(x.data(), x.data() + 3 * n);
  std::vector<std::uint32_t> nbr(n * k1);
  for (std::size_t i = 0; i < n * k1; ++i) nbr[i] = static_cast<std::uint32_t>((i * 7919) % n);
  const std::vector<double> a = detail::pcaCovariances(Device::reference(), Precision::Float, pos, k1, nbr);
  const std::vector<double> b = detail::pcaCovariances(dev, Precision::Float, pos, k1, nbr);
  REQUIRE(a.size() == b.size());
  double diff = 0;
  for (std::size_t i = 0; i < a.size(); ++i) diff = std::max(diff, std::abs(a[i] - b[i]));
  CHECK(diff < 1e-6);
}

TEST_CASE("normals: noisy sphere and two separate spheres are oriented outward") {
  const Device ref = Device::reference();
  SUBCASE("noise of 0.5% of the radius") {
    const PointSet noisy = testing::noisySphere(8000, 0.5, 0.0025);
    const PointSet est = estimateNormals(ref, noisy.positions(), NormalOptions{}).points;
    double mean = 0;
    std::size_t outward = 0;
    for (Eigen::Index i = 0; i < est.normals().rows(); ++i) {
      const double a = testing::angleDeg(est.normals().row(i), est.positions().row(i).normalized());
      mean += a;
      outward += a < 90 ? 1 : 0;
    }
    mean /= static_cast<double>(est.size());
    MESSAGE("noisy sphere: mean angle " << mean << " deg");
    CHECK(outward == est.size());
    CHECK(mean < 10.0);
  }
  SUBCASE("two spheres of different sizes, far apart") {
    Points n1, n2;
    const Points a = testing::fibonacciSphere(3000, 0.5, &n1);
    Points b = testing::fibonacciSphere(2000, 0.2, &n2);
    b.rowwise() += Eigen::RowVector3d(2.0, 0.3, -0.5);
    Points p(a.rows() + b.rows(), 3), truth(a.rows() + b.rows(), 3);
    p << a, b;
    truth << n1, n2;
    // Rotate the cloud so that no sphere's top is exactly +z (the seed rule is then not trivially right).
    const Eigen::Matrix3d r = Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    p = (p * r.transpose()).eval();
    truth = (truth * r.transpose()).eval();
    const NormalResult estResult = estimateNormals(ref, p, NormalOptions{});
    const PointSet& est = estResult.points;
    const NormalReport& rep = estResult.report;
    CHECK(rep.components == 2);
    CHECK(rep.ambiguousComponents == 0);
    CHECK(rep.nestedComponents == 0);
    std::size_t outward = 0;
    for (Eigen::Index i = 0; i < p.rows(); ++i) outward += est.normals().row(i).dot(truth.row(i)) > 0.99 ? 1 : 0;
    CHECK(outward == est.size());
  }
}

TEST_CASE("normals: a hollow shell's inner wall faces its cavity") {
  Points n1, n2;
  const Points a = testing::fibonacciSphere(4000, 0.5, &n1);
  const Points b = testing::fibonacciSphere(2500, 0.35, &n2);
  Points p(a.rows() + b.rows(), 3), truth(a.rows() + b.rows(), 3);
  p << a, b;
  truth << n1, -n2;  // the solid is the shell between the spheres: the inner sphere's outward side is inward
  const NormalResult estResult = estimateNormals(Device::reference(), p, NormalOptions{});
  const PointSet& est = estResult.points;
  const NormalReport& rep = estResult.report;
  CHECK(rep.components == 2);
  CHECK(rep.nestedComponents == 1);
  std::size_t right = 0;
  for (Eigen::Index i = 0; i < p.rows(); ++i) right += est.normals().row(i).dot(truth.row(i)) > 0.99 ? 1 : 0;
  CHECK(right == est.size());
}

TEST_CASE("normals: duplicates share a normal") {
  Points n1;
  const Points a = testing::fibonacciSphere(1000, 0.5, &n1);
  Points p(a.rows() + 3, 3);
  p << a, a.row(5), a.row(5), a.row(17);
  const NormalResult estResult = estimateNormals(Device::reference(), p, NormalOptions{});
  const PointSet& est = estResult.points;
  const NormalReport& rep = estResult.report;
  CHECK(rep.duplicates == 3);
  CHECK(est.size() == p.rows());
  CHECK(est.normals().row(1000) == est.normals().row(5));
  CHECK(est.normals().row(1001) == est.normals().row(5));
  CHECK(est.normals().row(1002) == est.normals().row(17));
  CHECK(est.normals().row(5).dot(n1.row(5)) > 0.99);
}

TEST_CASE("normals: bad input") {
  const Device ref = Device::reference();
  Points n1;
  Points sphere = testing::fibonacciSphere(500, 0.5, &n1);
  SUBCASE("NaN coordinate names the point") {
    sphere(123, 1) = std::numeric_limits<double>::quiet_NaN();
    checkInvalid([&] { estimateNormals(ref, sphere, NormalOptions{}).points; }, {"point 123", "non-finite"});
  }
  SUBCASE("k too small, k too large, too few points") {
    NormalOptions o;
    o.k = 2;
    checkInvalid([&] { estimateNormals(ref, sphere, o).points; }, {"k must be at least 3"});
    o.k = 500;
    checkInvalid([&] { estimateNormals(ref, sphere, o).points; }, {"k = 500", "at least 501 distinct points", "got 500"});
    checkInvalid([&] { estimateNormals(ref, sphere.topRows(10), NormalOptions{}).points; }, {"at least 16", "got 10"});
  }
  SUBCASE("duplicates leave too few distinct points") {
    Points p(40, 3);
    for (Eigen::Index i = 0; i < 40; ++i) p.row(i) = sphere.row(i % 8);
    checkInvalid([&] { estimateNormals(ref, p, NormalOptions{}).points; }, {"got 8", "32 exact duplicates"});
  }
  SUBCASE("all points on a line") {
    Points p(100, 3);
    for (Eigen::Index i = 0; i < 100; ++i) p.row(i) = Eigen::RowVector3d(1, 2, 3) * (0.01 * static_cast<double>(i));
    checkInvalid([&] { estimateNormals(ref, p, NormalOptions{}).points; }, {"line", "undefined"});
  }
  SUBCASE("all points on a plane: error, or consistent normals on request") {
    Points p(400, 3);
    for (Eigen::Index i = 0; i < 400; ++i) {
      const double x = 0.05 * static_cast<double>(i % 20), y = 0.05 * static_cast<double>(i / 20);
      p.row(i) = Eigen::RowVector3d(x, y, 0.3 * x - 0.2 * y + 1.0);
    }
    checkInvalid([&] { estimateNormals(ref, p, NormalOptions{}).points; }, {"plane", "no outward side"});
    NormalOptions o;
    o.requireOutward = false;
    const NormalResult estResult = estimateNormals(ref, p, o);
    const PointSet& est = estResult.points;
    const NormalReport& rep = estResult.report;
    CHECK(rep.ambiguousComponents == 1);
    const Eigen::RowVector3d up = Eigen::RowVector3d(-0.3, 0.2, 1.0).normalized();
    for (Eigen::Index i = 0; i < est.normals().rows(); ++i) CHECK(est.normals().row(i).dot(up) > 0.999);
  }
  SUBCASE("a noisy flat patch has no outward side") {
    Points p = testing::noisySphere(900, 0.5, 0.0).positions();
    for (Eigen::Index i = 0; i < p.rows(); ++i) p(i, 2) = 0.001 * std::sin(37.0 * static_cast<double>(i));
    checkInvalid([&] { estimateNormals(ref, p, NormalOptions{}).points; }, {"encloses no volume", "flat or open"});
  }
}

}  // TEST_SUITE
