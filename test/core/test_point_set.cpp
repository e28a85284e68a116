// PointSet: constructor validation and normal normalisation, bounds, duplicate merging (exact and
// with a tolerance, normals averaged or cancelled) and the fittability checks with their messages.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/point_set.hpp"
#include "shapes.hpp"

namespace {

using duplexfit::checkFittable;
using duplexfit::InvalidArgument;
using duplexfit::Points;
using duplexfit::PointSet;

/// The message of the InvalidArgument thrown by `action` ("" when none is thrown).
template <typename Action>
std::string invalidArgumentMessage(Action&& action) {
  try {
    action();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return {};
}

/// n random points in the unit cube with random unit normals, from a fixed seed.
PointSet randomCloud(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Points p(n, 3), q(n, 3);
  for (int i = 0; i < n; ++i) {
    p.row(i) << u(rng), u(rng), u(rng);
    q.row(i) << u(rng), u(rng), u(rng) + 2.0;
  }
  return PointSet(p, q);
}

/// n normals (0, 0, 1).
Points upNormals(int n) {
  Points q = Points::Zero(n, 3);
  q.col(2).setOnes();
  return q;
}

}  // namespace

TEST_SUITE("io") {

TEST_CASE("point set: the constructor validates and normalises") {
  Points p(3, 3), n(3, 3);
  p << 0, 0, 0, 1, 2, 3, -1, 0, 5;
  n << 0, 0, 2, 3, 4, 0, 1e-13, 0, 0;
  const PointSet s(p, n);
  CHECK(s.size() == 3);
  CHECK(s.positions() == p);
  CHECK(s.normals()(0, 2) == 1.0);
  CHECK(s.normals()(1, 0) == doctest::Approx(0.6));
  CHECK(s.normals()(1, 1) == doctest::Approx(0.8));
  CHECK(s.normals().row(2).isZero(0.0));
  CHECK(s.zeroNormals() == 1);

  const Eigen::AlignedBox3d box = s.bounds();
  CHECK(box.min() == Eigen::Vector3d(-1, 0, 0));
  CHECK(box.max() == Eigen::Vector3d(1, 2, 5));
  CHECK(PointSet().bounds().isEmpty());
  CHECK(PointSet().size() == 0);

  const std::string mismatch = invalidArgumentMessage([&] { (void)PointSet(p, Points(2, 3)); });
  CHECK(mismatch.find("3 positions but 2") != std::string::npos);
  Points bad = p;
  bad(2, 1) = std::numeric_limits<double>::quiet_NaN();
  const std::string nan = invalidArgumentMessage([&] { (void)PointSet(bad, n); });
  CHECK(nan.find("position of point 2") != std::string::npos);
  Points badNormal = n;
  badNormal(1, 0) = std::numeric_limits<double>::infinity();
  const std::string message = invalidArgumentMessage([&] { (void)PointSet(p, badNormal); });
  CHECK(message.find("normal of point 1") != std::string::npos);

  PointSet flipped = s;
  flipped.flipNormals();
  CHECK(flipped.normals() == -s.normals());
}

TEST_CASE("point set: mergeDuplicates averages normals, keeps order, cancels opposites") {
  Points p(7, 3), n(7, 3);
  p << 0, 0, 0,  //
      1, 0, 0,   //
      0, 0, 0,   // duplicate of 0
      2, 0, 0,   //
      2, 0, 0,   // duplicate of 3, opposite normal
      1, 0, -0,  // duplicate of 1 (−0 == +0)
      0, 0, 0;   // third copy of 0
  n << 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 1, 0, 0, 0;
  PointSet s(p, n);
  CHECK(s.mergeDuplicates() == 4);
  REQUIRE(s.size() == 3);
  CHECK(s.positions().row(0) == Eigen::RowVector3d(0, 0, 0));
  CHECK(s.positions().row(1) == Eigen::RowVector3d(1, 0, 0));
  CHECK(s.positions().row(2) == Eigen::RowVector3d(2, 0, 0));
  CHECK(s.normals()(0, 0) == doctest::Approx(std::sqrt(0.5)));
  CHECK(s.normals()(0, 1) == doctest::Approx(std::sqrt(0.5)));
  CHECK(s.normals()(1, 1) == doctest::Approx(std::sqrt(0.5)));
  CHECK(s.normals()(1, 2) == doctest::Approx(std::sqrt(0.5)));
  CHECK(s.normals().row(2).isZero(0.0));
  CHECK(s.zeroNormals() == 1);
  CHECK(s.mergeDuplicates() == 0);  // idempotent
}

TEST_CASE("point set: mergeDuplicates with a tolerance and on a large cloud") {
  Points p(4, 3), n(4, 3);
  p << 0, 0, 0, 1e-9, 0, 0, 10, 10, 10, 10, 10, 10 + 1e-9;
  n.setZero();
  n.col(2).setOnes();
  PointSet exact(p, n);
  CHECK(exact.mergeDuplicates() == 0);
  PointSet rounded(p, n);
  CHECK(rounded.mergeDuplicates(1e-6) == 2);
  CHECK(rounded.size() == 2);
  CHECK(rounded.positions().row(1) == Eigen::RowVector3d(10, 10, 10));
  CHECK_THROWS_AS(rounded.mergeDuplicates(-1.0), InvalidArgument);

  // 20k points, each duplicated once in a shuffled order: half are removed, deterministically.
  const PointSet base = randomCloud(20000, 7);
  Points p2(40000, 3), n2(40000, 3);
  std::vector<int> order(40000);
  for (int i = 0; i < 40000; ++i) order[static_cast<std::size_t>(i)] = i % 20000;
  std::shuffle(order.begin(), order.end(), std::mt19937(3));
  for (int i = 0; i < 40000; ++i) {
    p2.row(i) = base.positions().row(order[static_cast<std::size_t>(i)]);
    n2.row(i) = base.normals().row(order[static_cast<std::size_t>(i)]);
  }
  PointSet twice(p2, n2), again(p2, n2);
  CHECK(twice.mergeDuplicates() == 20000);
  CHECK(again.mergeDuplicates() == 20000);
  CHECK(twice.positions() == again.positions());
  CHECK(twice.normals() == again.normals());
  CHECK(twice.positions().row(0) == p2.row(0));
  CHECK((twice.normals().rowwise().norm().array() - 1.0).abs().maxCoeff() < 1e-12);
  // The groups in the order of their first point, each the sum of its points' normals in input order,
  // normalised: against a first-seen map built here.
  std::map<std::array<double, 3>, int> seen;
  std::vector<Eigen::RowVector3d> sums, firstPosition;
  for (int i = 0; i < 40000; ++i) {
    const std::array<double, 3> key{p2(i, 0), p2(i, 1), p2(i, 2)};
    const auto it = seen.emplace(key, static_cast<int>(sums.size())).first;
    if (it->second == static_cast<int>(sums.size())) {
      sums.push_back(Eigen::RowVector3d::Zero());
      firstPosition.push_back(p2.row(i));
    }
    sums[static_cast<std::size_t>(it->second)] += n2.row(i);
  }
  REQUIRE(sums.size() == twice.size());
  std::size_t differ = 0;
  for (std::size_t g = 0; g < sums.size(); ++g) {
    const auto row = static_cast<Eigen::Index>(g);
    // (the normal to rounding: Eigen may sum the norm of a matrix row in another order than a vector's)
    if (twice.positions().row(row) != firstPosition[g] ||
        (twice.normals().row(row) - sums[g] / sums[g].norm()).cwiseAbs().maxCoeff() > 1e-15) {
      ++differ;
    }
  }
  CHECK(differ == 0);
}

TEST_CASE("point set: checkFittable accepts surfaces and explains what is wrong otherwise") {
  Points normals;
  const Points sphere = duplexfit::testing::fibonacciSphere(100, 0.5, &normals);
  CHECK_NOTHROW(checkFittable(PointSet(sphere, normals), "sphere.ply"));

  // A flat square is fittable (a plate), and so is a thin needle of real width.
  Points plane(25, 3);
  for (int i = 0; i < 25; ++i) plane.row(i) << i % 5, i / 5, 0.0;
  CHECK_NOTHROW(checkFittable(PointSet(plane, upNormals(25)), "plane.ply"));

  Points seven(7, 3);
  for (int i = 0; i < 7; ++i) seven.row(i) << i, i * i, 0.0;
  const PointSet few(seven, upNormals(7));
  CHECK(invalidArgumentMessage([&] { checkFittable(few, "cloud.ply"); }) ==
        "cloud.ply: only 7 points; fitting needs at least 10");

  Points same = Points::Constant(12, 3, 3.5);
  std::string message = invalidArgumentMessage(
      [&] { checkFittable(PointSet(same, upNormals(12)), "same.ply"); });
  CHECK(message.rfind("same.ply: all 12 points are at the same position", 0) == 0);

  Points line(30, 3);
  for (int i = 0; i < 30; ++i) {
    const double t = i * 0.1;
    // On a skew line, with rounding-level noise off it.
    line.row(i) << 1.0 + t, 2.0 - 2.0 * t, 0.5 * t + ((i % 3) - 1) * 1e-15;
  }
  message = invalidArgumentMessage([&] { checkFittable(PointSet(line, upNormals(30)), "l.xyz"); });
  CHECK(message.rfind("l.xyz: all 30 points lie on one line", 0) == 0);
  line(7, 1) += 0.01;  // one point clearly off the line
  CHECK_NOTHROW(checkFittable(PointSet(line, upNormals(30)), "l.xyz"));

  message = invalidArgumentMessage(
      [&] { checkFittable(PointSet(sphere, Points::Zero(100, 3)), "zero.ply"); });
  CHECK(message.rfind("zero.ply: all 100 normals are zero", 0) == 0);
  Points someZero = normals;
  someZero.topRows(99).setZero();
  CHECK_NOTHROW(checkFittable(PointSet(sphere, someZero), "one.ply"));
}

}  // TEST_SUITE
