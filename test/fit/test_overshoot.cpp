// The overshoot check at the finest level (FitOptions::overshootCheck, docs/method.md "Overshoot between
// sparse samples"): points D = 1.5 median spacings off the surface, on the off-surface side, with no other
// input point within D, must not be left less than D/2 on their side by level M's bumps. On a well-sampled
// sphere nothing is added and the field is the plain fit's; on wheel_29k (sparse samples on sharp ridges)
// the points where f overshoots become constraints and most of the overshoot goes.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "data.hpp"
#include "duplexfit/communicator.hpp"
#include "duplexfit/distributed.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/winding.hpp"
#include "fit/fit_detail.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

const Device& fitDevice() { return testing::openclOrReferenceDevice(); }

/// The check's distance D in input units: overshootSpacings median spacings (the fit's rule, in the
/// normalised box of side 1).
double checkDistance(const PointSet& cloud, const FitOptions& o) {
  const Points& p = cloud.positions();
  const double side = (p.colwise().maxCoeff() - p.colwise().minCoeff()).maxCoeff();
  const Points u = p / side;
  const Eigen::VectorXd areas = estimatePointAreas(u, cloud.normals(), WindingOptions().areaNeighbors, NeighborIndex(u));
  return o.overshootSpacings * detail::medianSpacing(areas) * side;
}

/// The outside points p + D·n (n outward) with no other input point within D where f is above −D/2: where
/// the field puts empty space less than half its distance outside.
std::size_t overshooting(const FitResult& r, const PointSet& cloud, double d) {
  const Points& p = cloud.positions();
  const Points q = p + d * cloud.normals();
  std::vector<Index> exclude(static_cast<std::size_t>(p.rows()));
  for (std::size_t i = 0; i < exclude.size(); ++i) exclude[i] = static_cast<Index>(i);
  const NeighborLists other = NeighborIndex(p).anyOtherWithin(q, exclude, std::vector<double>(exclude.size(), d));
  const Eigen::VectorXd f = r.field.evaluate(fitDevice(), q).values;
  std::size_t count = 0;
  for (Eigen::Index i = 0; i < q.rows(); ++i) {
    if (other.count(static_cast<std::size_t>(i)) == 0 && f[i] > -0.5 * d) ++count;
  }
  return count;
}

/// wheel_29k (sparse samples on sharp ridges), duplicates merged, and the fit options of its tests.
PointSet wheelCloud(const std::string& dataDir) {
  PointSet cloud = readPointCloud(dataDir + "/clouds/wheel_29k.ply");
  cloud.mergeDuplicates();
  return cloud;
}
FitOptions wheelOptions() {
  FitOptions o;
  o.offsets = {0.025};
  return o;
}

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("overshoot check: a well-sampled sphere adds no constraint and keeps the plain fit's field") {
    Points normals;
    const Points p = testing::fibonacciSphere(3000, 0.4, &normals);
    const PointSet cloud(p, normals);
    FitOptions o;
    o.offsets = {0.05};
    const FitResult on = fit(fitDevice(), cloud, o);
    o.overshootCheck = false;
    const FitResult off = fit(fitDevice(), cloud, o);
    const LevelReport& finest = on.report.levelReports.back();
    CHECK(finest.overshootSites == 0);
    CHECK(finest.overshootRounds == 0);
    REQUIRE(on.field.levels().size() == off.field.levels().size());
    CHECK(on.field.levels().back().centres == off.field.levels().back().centres);
    CHECK(on.field.levels().back().weights == off.field.levels().back().weights);
    CHECK(overshooting(on, cloud, checkDistance(cloud, FitOptions{})) == 0);
  }

  TEST_CASE("overshoot check: its distance and rounds out of range are refused") {
    Points normals;
    const Points p = testing::fibonacciSphere(200, 0.4, &normals);
    const PointSet cloud(p, normals);
    for (const double spacings : {0.0, -1.0, std::nan(""), 1e9}) {
      CAPTURE(spacings);
      FitOptions o;
      o.overshootSpacings = spacings;
      CHECK_THROWS_AS(fit(Device::reference(), cloud, o), InvalidArgument);
    }
    FitOptions o;
    o.overshootRounds = -1;
    CHECK_THROWS_AS(fit(Device::reference(), cloud, o), InvalidArgument);
  }

  TEST_CASE("overshoot check: wheel_29k's points off its sparsely sampled ridges stay outside") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (the sphere case runs the check's code there)");
#endif
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    const PointSet cloud = wheelCloud(dir);
    FitOptions o = wheelOptions();
    const double d = checkDistance(cloud, o);
    const FitResult on = fit(fitDevice(), cloud, o);
    o.overshootCheck = false;
    const FitResult off = fit(fitDevice(), cloud, o);
    const std::size_t before = overshooting(off, cloud, d), after = overshooting(on, cloud, d);
    CAPTURE(before);
    CAPTURE(after);
    CHECK(before >= 20);
    CHECK(4 * after <= before);
    const LevelReport& finest = on.report.levelReports.back();
    CHECK(finest.overshootSites > 0);
    CHECK(finest.overshootRounds >= 1);
    CHECK(finest.centres == static_cast<std::size_t>(on.field.levels().back().centres.rows()));
    // The surface is held as before.
    CHECK(on.report.e0 <= 2.0 * off.report.e0 + 1e-7);
    CHECK(on.report.eDelta[0] <= 2.0 * off.report.eDelta[0] + 1e-7);
  }

  TEST_CASE("overshoot check in the fit by blocks: one block is fit()'s field bit for bit, four blocks repair as much") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (the sphere case runs the check's code there)");
#endif
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    const PointSet cloud = wheelCloud(dir);
    const FitOptions o = wheelOptions();
    const double d = checkDistance(cloud, o);
    const FitResult serial = fit(fitDevice(), cloud, o);
    const std::unique_ptr<Communicator> comm = makeSerialCommunicator();
    const auto n = static_cast<std::int64_t>(cloud.size());
    DistributedReport r1;
    const FitResult one = fitDistributed(fitDevice(), *comm, partitionPoints(*comm, cloud, 0, n, r1, 1), o, DistributedOptions{}, r1);
    REQUIRE(one.field.levels().size() == serial.field.levels().size());
    CHECK(one.field.levels().back().centres == serial.field.levels().back().centres);
    CHECK(one.field.levels().back().weights == serial.field.levels().back().weights);
    CHECK(one.report.levelReports.back().overshootSites == serial.report.levelReports.back().overshootSites);
    // Four blocks, the finest levels solved block by block (not gathered): without the check its field
    // overshoots as fit()'s does, with it (the default) as little as fit()'s.
    DistributedOptions blocks;
    blocks.coarsePoints = 5000;
    FitOptions offOptions = o;
    offOptions.overshootCheck = false;
    DistributedReport r4, r4off;
    const FitResult four = fitDistributed(fitDevice(), *comm, partitionPoints(*comm, cloud, 0, n, r4, 4), o, blocks, r4);
    const FitResult fourOff =
        fitDistributed(fitDevice(), *comm, partitionPoints(*comm, cloud, 0, n, r4off, 4), offOptions, blocks, r4off);
    REQUIRE(!r4.rankReports.empty());
    CHECK_FALSE(r4.rankReports.front().levels.back().gathered);
    const std::size_t before = overshooting(fourOff, cloud, d), after = overshooting(four, cloud, d),
                      serialAfter = overshooting(serial, cloud, d);
    CAPTURE(before);
    CAPTURE(after);
    CAPTURE(serialAfter);
    CHECK(before >= 20);
    CHECK(after <= serialAfter + 2);
    CHECK(four.report.levelReports.back().overshootSites > 0);
    CHECK(four.report.levelReports.back().overshootRounds >= 1);
    CHECK(four.report.e0 <= 2.0 * fourOff.report.e0 + 1e-7);
  }
}
