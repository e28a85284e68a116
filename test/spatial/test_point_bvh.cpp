// PointBvh::nearestOther (the companions' validity test, docs/method.md §3.1) against the k-d tree's two
// nearest neighbours without the excluded point: the same point and the same distance, bit for bit, for
// queries on and far from a dense sampled sphere, with duplicate points, lattice ties, no exclusion,
// a set of one point, and bad arguments.
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/neighbors.hpp"
#include "spatial/point_bvh.hpp"

namespace {

using duplexfit::Index;
using duplexfit::Points;
using duplexfit::detail::PointBvh;

void checkAgainstReference(const Points& points, const Points& queries, const std::vector<Eigen::Index>& exclude) {
  std::vector<double> d, dRef;
  std::vector<Eigen::Index> n, nRef;
  const PointBvh bvh(points);
  CHECK(bvh.size() == static_cast<std::size_t>(points.rows()));
  bvh.nearestOther(queries, exclude, d, n);
  duplexfit::detail::nearestOtherInTree(duplexfit::NeighborIndex(points), queries, exclude, dRef, nRef);
  REQUIRE(d.size() == dRef.size());
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (n[i] != nRef[i] || !(d[i] == dRef[i] || (std::isinf(d[i]) && std::isinf(dRef[i])))) ++mismatches;
  }
  CHECK(mismatches == 0);
}

}  // namespace

TEST_SUITE("spatial") {
  TEST_CASE("point bvh: the nearest other point equals the k-d tree's, on and far from a dense sphere") {
    std::mt19937 engine(7u);
    std::normal_distribution<double> g(0.0, 1.0);
    const int n = 40000;
    Points p(n, 3), nu(n, 3);
    for (int i = 0; i < n; ++i) {
      Eigen::Vector3d v(g(engine), g(engine), g(engine));
      v.normalize();
      nu.row(i) = v.transpose();
      p.row(i) = 0.5 * v.transpose();
    }
    // Duplicates: every 97th point repeated, so that its nearest other is at distance 0.
    for (int i = 0; i < n; i += 97) p.row((i + 1) % n) = p.row(i);
    for (const double step : {0.0, 0.002, 0.05, -0.05, 0.3, 0.5}) {
      CAPTURE(step);
      // Inward: 0.5 reaches the centre (every point ties). Far queries search much of the sphere, so
      // they take every 16th point only (the sanitizer build).
      const int stride = step > 0.1 ? 16 : 1;
      Points q(n / stride, 3);
      std::vector<Eigen::Index> src(static_cast<std::size_t>(n / stride));
      for (int k = 0; k < n / stride; ++k) {
        q.row(k) = p.row(k * stride) - step * nu.row(k * stride);
        src[static_cast<std::size_t>(k)] = k * stride;
      }
      checkAgainstReference(p, q, src);
    }
    // No exclusion: the nearest point itself.
    checkAgainstReference(p, p, std::vector<Eigen::Index>(static_cast<std::size_t>(n), -1));
  }

  TEST_CASE("point bvh: lattice ties go to the smaller index, and degenerate sets") {
    // A 12³ lattice queried from cell centres and from nodes: many exact ties.
    Points lattice(12 * 12 * 12, 3);
    int r = 0;
    for (int i = 0; i < 12; ++i) {
      for (int j = 0; j < 12; ++j) {
        for (int k = 0; k < 12; ++k) lattice.row(r++) << 0.1 * i, 0.1 * j, 0.1 * k;
      }
    }
    Points centres = (lattice.array() + 0.05).matrix();
    std::vector<Eigen::Index> exclude(static_cast<std::size_t>(lattice.rows()));
    for (std::size_t i = 0; i < exclude.size(); ++i) exclude[i] = static_cast<Eigen::Index>((i * 7) % exclude.size());
    checkAgainstReference(lattice, centres, exclude);
    checkAgainstReference(lattice, lattice, exclude);

    // One point, excluded: none. Empty set: none.
    const Points one = Points::Zero(1, 3);
    std::vector<double> d;
    std::vector<Eigen::Index> nearest;
    PointBvh(one).nearestOther(one, {0}, d, nearest);
    CHECK(std::isinf(d[0]));
    CHECK(nearest[0] == -1);
    PointBvh(Points(0, 3)).nearestOther(one, {-1}, d, nearest);
    CHECK(nearest[0] == -1);

    // Bad arguments.
    Points bad = lattice;
    bad(5, 1) = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_WITH_AS(PointBvh{bad}, doctest::Contains("row 5"), duplexfit::InvalidArgument);
    const PointBvh bvh(lattice);
    CHECK_THROWS_AS(bvh.nearestOther(lattice, {0, 1}, d, nearest), duplexfit::InvalidArgument);
    CHECK_THROWS_WITH_AS(bvh.nearestOther(bad, exclude, d, nearest), doctest::Contains("row 5"), duplexfit::InvalidArgument);
    // Cancelled at its first poll.
    class Stop final : public duplexfit::Interrupter {
     public:
      bool wasInterrupted(int) override { return true; }
    };
    Stop stop;
    CHECK_THROWS_AS(bvh.nearestOther(lattice, exclude, d, nearest, &stop), duplexfit::Cancelled);
  }
}
