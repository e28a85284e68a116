// NeighborIndex against brute force (nanoflann's test pattern): radius and k-nearest queries on
// random clouds with duplicates, lattice ties at the radius boundary, empty inputs and argument
// errors.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/interrupter.hpp"
#include "duplexfit/neighbors.hpp"

namespace {

using duplexfit::Index;
using duplexfit::InvalidArgument;
using duplexfit::NeighborIndex;
using duplexfit::NeighborLists;
using duplexfit::Points;

/// Uniform points in the unit cube from a fixed seed.
Points randomPoints(int n, std::uint32_t seed) {
  std::mt19937 engine(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Points p(n, 3);
  for (int i = 0; i < n; ++i) p.row(i) << u(engine), u(engine), u(engine);
  return p;
}

/// The same arithmetic as the index: ‖q − p‖ = √((q−p)ₓ² + (q−p)ᵧ² + (q−p)𝓏²), left to right.
double distance(const Points& a, Eigen::Index i, const Points& b, Eigen::Index j) {
  const double dx = a(i, 0) - b(j, 0);
  const double dy = a(i, 1) - b(j, 1);
  const double dz = a(i, 2) - b(j, 2);
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

/// Brute force: all (distance, index) pairs of each query sorted, truncated by radius or by k.
NeighborLists bruteForce(const Points& points, const Points& queries, double radius, int k) {
  NeighborLists out;
  std::vector<std::pair<double, Index>> all;
  for (Eigen::Index i = 0; i < queries.rows(); ++i) {
    all.clear();
    for (Eigen::Index j = 0; j < points.rows(); ++j) {
      const double d = distance(queries, i, points, j);
      if (d < radius) all.emplace_back(d, static_cast<Index>(j));
    }
    if (k > 0 && all.size() > static_cast<std::size_t>(k)) {
      std::nth_element(all.begin(), all.begin() + k, all.end());  // (distance, index) is a total order
      all.resize(static_cast<std::size_t>(k));
    }
    std::sort(all.begin(), all.end());
    for (const auto& [d, j] : all) {
      out.indices.push_back(j);
      out.distances.push_back(d);
    }
    out.offsets.push_back(static_cast<std::int64_t>(out.indices.size()));
  }
  return out;
}

void requireSameLists(const NeighborLists& got, const NeighborLists& want) {
  REQUIRE(got.queries() == want.queries());
  REQUIRE(got.offsets == want.offsets);
  REQUIRE(got.indices.size() == got.distances.size());
  for (std::size_t q = 0; q < got.queries(); ++q) {
    for (auto k = got.offsets[q]; k < got.offsets[q + 1]; ++k) {
      const auto e = static_cast<std::size_t>(k);
      INFO("query " << q << ", entry " << k - got.offsets[q]);
      REQUIRE(got.indices[e] == want.indices[e]);
      REQUIRE(got.distances[e] == doctest::Approx(want.distances[e]).epsilon(1e-15));
    }
  }
}

/// A random cloud of 2000 points whose last 200 rows duplicate earlier ones (some several times).
Points cloudWithDuplicates() {
  Points p = randomPoints(2000, 7u);
  std::mt19937 engine(11u);
  std::uniform_int_distribution<int> pick(0, 1799);
  for (int i = 1800; i < 2000; ++i) p.row(i) = p.row(pick(engine));
  return p;
}

/// 300 queries: 200 random points (not in the set) and 100 rows of the set itself.
Points mixedQueries(const Points& points) {
  Points q(300, 3);
  q.topRows(200) = randomPoints(200, 99u);
  for (int i = 0; i < 100; ++i) q.row(200 + i) = points.row((i * 37) % points.rows());
  return q;
}

/// The integer lattice {0..4}³ (125 points): many exact ties and exact boundary distances.
Points lattice() {
  Points p(125, 3);
  int r = 0;
  for (int x = 0; x < 5; ++x) {
    for (int y = 0; y < 5; ++y) {
      for (int z = 0; z < 5; ++z) p.row(r++) << x, y, z;
    }
  }
  return p;
}

}  // namespace

TEST_SUITE("spatial") {
  TEST_CASE("neighbors: radius search equals brute force on a cloud with duplicates") {
    const Points points = cloudWithDuplicates();
    const Points queries = mixedQueries(points);
    const NeighborIndex index(points);
    CHECK(index.size() == 2000);
    for (double radius : {1e-9, 0.01, 0.05, 0.15, 0.4, 10.0}) {
      CAPTURE(radius);
      const NeighborLists got = index.radiusSearch(queries, radius);
      requireSameLists(got, bruteForce(points, queries, radius, 0));
      if (radius == 10.0) CHECK(got.count(0) == 2000);
    }
    // A set point always finds itself, and its duplicates at distance 0 in index order.
    const NeighborLists self = index.radiusSearch(points, 1e-9);
    for (Eigen::Index i = 0; i < points.rows(); ++i) {
      const auto first = static_cast<std::size_t>(self.offsets[static_cast<std::size_t>(i)]);
      REQUIRE(self.count(static_cast<std::size_t>(i)) >= 1);
      CHECK(self.distances[first] == 0.0);
    }
  }

  TEST_CASE("neighbors: the unsorted radius search finds the same hits, in a deterministic order") {
    const Points points = cloudWithDuplicates();
    const Points queries = mixedQueries(points);
    const NeighborIndex index(points);
    for (double radius : {1e-9, 0.05, 0.4}) {
      CAPTURE(radius);
      const NeighborLists sorted = index.radiusSearch(queries, radius);
      const NeighborLists unsorted = index.radiusSearchUnsorted(queries, radius);
      REQUIRE(unsorted.offsets == sorted.offsets);
      // Sorting each query's hits by (distance, index) gives the sorted search's lists exactly.
      NeighborLists resorted = unsorted;
      for (std::size_t q = 0; q + 1 < resorted.offsets.size(); ++q) {
        std::vector<std::pair<double, Index>> hits;
        for (auto e = resorted.offsets[q]; e < resorted.offsets[q + 1]; ++e) {
          hits.emplace_back(resorted.distances[static_cast<std::size_t>(e)], resorted.indices[static_cast<std::size_t>(e)]);
        }
        std::sort(hits.begin(), hits.end());
        for (std::size_t k = 0; k < hits.size(); ++k) {
          resorted.distances[static_cast<std::size_t>(resorted.offsets[q]) + k] = hits[k].first;
          resorted.indices[static_cast<std::size_t>(resorted.offsets[q]) + k] = hits[k].second;
        }
      }
      CHECK(resorted.indices == sorted.indices);
      CHECK(resorted.distances == sorted.distances);
      const NeighborLists again = index.radiusSearchUnsorted(queries, radius);
      CHECK(again.indices == unsorted.indices);
    }
    CHECK_THROWS_AS(index.radiusSearchUnsorted(queries, 0.0), InvalidArgument);
  }

  TEST_CASE("neighbors: nearestWithin is the nearest point when it lies within the radius, else none") {
    const Points points = cloudWithDuplicates();
    const Points queries = mixedQueries(points);
    const NeighborIndex index(points);
    const NeighborLists nearest = index.knnSearch(queries, 1);
    for (double radius : {1e-9, 0.01, 0.05, 0.4}) {
      CAPTURE(radius);
      const NeighborLists within = index.nearestWithin(queries, radius);
      std::size_t found = 0;
      for (std::size_t q = 0; q + 1 < nearest.offsets.size(); ++q) {
        const auto e = static_cast<std::size_t>(nearest.offsets[q]);
        const bool inside = nearest.distances[e] <= radius;
        REQUIRE(within.count(q) == (inside ? 1U : 0U));
        if (inside) {
          ++found;
          CHECK(within.indices[static_cast<std::size_t>(within.offsets[q])] == nearest.indices[e]);
          CHECK(within.distances[static_cast<std::size_t>(within.offsets[q])] == nearest.distances[e]);
        }
      }
      if (radius == 0.4) CHECK(found == static_cast<std::size_t>(queries.rows()));
      if (radius == 0.05) CHECK(found > 0);
    }
    CHECK_THROWS_AS(index.nearestWithin(queries, -1.0), InvalidArgument);
    CHECK(NeighborIndex(Points(0, 3)).nearestWithin(queries, 0.1).indices.empty());
  }

  TEST_CASE("neighbors: anyOtherWithin finds a point other than the excluded one exactly when brute force does") {
    const Points points = cloudWithDuplicates();
    const Points queries = mixedQueries(points);
    const NeighborIndex index(points);
    std::mt19937 engine(11u);
    std::uniform_real_distribution<double> u(0.0, 0.3);
    std::uniform_int_distribution<int> pick(-1, static_cast<int>(points.rows()) - 1);
    std::vector<Index> exclude(static_cast<std::size_t>(queries.rows()));
    std::vector<double> radius(exclude.size());
    for (std::size_t q = 0; q < exclude.size(); ++q) {
      exclude[q] = static_cast<Index>(pick(engine));
      radius[q] = q % 7 == 0 ? 0.0 : u(engine);
    }
    // Radii exactly at a nearest other point's distance (strict: not found) and one ulp beyond (found).
    for (std::size_t q = 0; q < exclude.size(); q += 5) {
      double best = std::numeric_limits<double>::infinity();
      for (Eigen::Index j = 0; j < points.rows(); ++j) {
        if (static_cast<Index>(j) != exclude[q]) best = std::min(best, distance(queries, static_cast<Eigen::Index>(q), points, j));
      }
      radius[q] = q % 10 == 0 ? best : std::nextafter(best, 2.0);
    }
    const NeighborLists got = index.anyOtherWithin(queries, exclude, radius);
    std::size_t found = 0;
    for (std::size_t q = 0; q < exclude.size(); ++q) {
      CAPTURE(q);
      bool near = false;
      for (Eigen::Index j = 0; j < points.rows(); ++j) {
        near = near || (static_cast<Index>(j) != exclude[q] &&
                        distance(queries, static_cast<Eigen::Index>(q), points, j) < radius[q]);
      }
      REQUIRE(got.count(q) == (near ? 1U : 0U));
      if (!near) continue;
      ++found;
      const auto e = static_cast<std::size_t>(got.offsets[q]);
      const Index j = got.indices[e];
      CHECK(j != exclude[q]);
      CHECK(got.distances[e] == distance(queries, static_cast<Eigen::Index>(q), points, j));
      CHECK(got.distances[e] < radius[q]);
    }
    CHECK(found > exclude.size() / 4);
    CHECK(found < exclude.size());
    CHECK_THROWS_AS(index.anyOtherWithin(queries, std::vector<Index>(3, -1), radius), InvalidArgument);
    radius[1] = std::numeric_limits<double>::quiet_NaN();
    CHECK_THROWS_AS(index.anyOtherWithin(queries, exclude, radius), InvalidArgument);
    CHECK(NeighborIndex(Points(0, 3)).anyOtherWithin(queries, exclude, std::vector<double>(exclude.size(), 1.0)).indices.empty());
  }

  TEST_CASE("neighbors: radius and knn search across many query blocks equal brute force") {
    const Points points = randomPoints(2500, 3u);
    const NeighborIndex index(points);
    const NeighborLists got = index.radiusSearch(points, 0.1);
    requireSameLists(got, bruteForce(points, points, 0.1, 0));
    CHECK(got.indices.size() > 2500 * 5);
    const double all = std::numeric_limits<double>::infinity();
    requireSameLists(index.knnSearch(points, 10), bruteForce(points, points, all, 10));
    // Repeated calls (which reuse per-thread buffers) give identical lists.
    const NeighborLists again = index.radiusSearch(points, 0.1);
    CHECK(again.offsets == got.offsets);
    CHECK(again.indices == got.indices);
    CHECK(again.distances == got.distances);
  }

  TEST_CASE("neighbors: radius is strict and ties sort by index on a lattice") {
    const Points points = lattice();
    const NeighborIndex index(points);
    Points centre(1, 3);
    centre << 2.0, 2.0, 2.0;
    const NeighborLists exact = index.radiusSearch(centre, 1.0);
    REQUIRE(exact.count(0) == 1);  // the six neighbours at distance exactly 1 are excluded
    const NeighborLists wider = index.radiusSearch(centre, std::nextafter(1.0, 2.0));
    REQUIRE(wider.count(0) == 7);
    CHECK(wider.indices[0] == 62);
    CHECK(std::is_sorted(wider.indices.begin() + 1, wider.indices.end()));
    for (double radius : {1.0, 1.5, std::sqrt(2.0), std::sqrt(3.0), 2.0, 3.0}) {
      CAPTURE(radius);
      requireSameLists(index.radiusSearch(points, radius), bruteForce(points, points, radius, 0));
    }
  }

  TEST_CASE("neighbors: knn equals brute force, ties broken by index") {
    const Points points = cloudWithDuplicates();
    const Points queries = mixedQueries(points);
    const NeighborIndex index(points);
    const double all = std::numeric_limits<double>::infinity();
    for (int k : {1, 2, 7, 13, 32, 33, 45, 200}) {  // 32 and 33: either side of the sorted collector's limit
      CAPTURE(k);
      requireSameLists(index.knnSearch(queries, k), bruteForce(points, queries, all, k));
    }
    const Points grid = lattice();
    const NeighborIndex latticeIndex(grid);
    for (int k : {1, 4, 7, 10, 27}) {
      CAPTURE(k);
      requireSameLists(latticeIndex.knnSearch(grid, k), bruteForce(grid, grid, all, k));
    }
  }

  TEST_CASE("neighbors: degenerate layouts (one point repeated, a plane, a line, far from the origin) equal brute force") {
    // The k-d tree splits on the widest axis at the median: a leaf of many copies of one point, boxes of zero
    // extent on an axis and coordinates large against the spacing must not lose or repeat a point.
    std::vector<Points> layouts;
    {
      Points p = randomPoints(600, 21u);
      for (int i = 0; i < 500; ++i) p.row(i) << 0.25, 0.5, 0.75;  // 500 copies, more than a leaf holds
      layouts.push_back(p);
    }
    {
      Points p = randomPoints(800, 22u);
      p.col(2).setConstant(0.5);  // a plane
      layouts.push_back(p);
    }
    {
      Points p = randomPoints(400, 23u);
      p.col(1) = p.col(0);
      p.col(2).setConstant(-2.0);  // a line
      layouts.push_back(p);
    }
    {
      Points p = randomPoints(700, 24u);
      p.array() += 1e6;  // far from the origin: spacing about 1e-8 of the coordinates
      layouts.push_back(p);
    }
    const double all = std::numeric_limits<double>::infinity();
    for (std::size_t l = 0; l < layouts.size(); ++l) {
      CAPTURE(l);
      const Points& points = layouts[l];
      Points queries = mixedQueries(points);
      if (l == 3) queries.topRows(200).array() += 1e6;
      const NeighborIndex index(points);
      for (int k : {1, 12, 40}) {
        CAPTURE(k);
        requireSameLists(index.knnSearch(queries, k), bruteForce(points, queries, all, k));
      }
      for (double radius : {0.02, 0.1, 0.3}) {
        CAPTURE(radius);
        requireSameLists(index.radiusSearch(queries, radius), bruteForce(points, queries, radius, 0));
        const NeighborLists nearest = index.nearestWithin(queries, radius);
        const NeighborLists want = bruteForce(points, queries, all, 1);
        for (std::size_t q = 0; q < want.queries(); ++q) {
          CAPTURE(q);
          const double d = want.distances[static_cast<std::size_t>(want.offsets[q])];
          if (d < 0.999 * radius) {
            REQUIRE(nearest.count(q) == 1);
            CHECK(nearest.indices[static_cast<std::size_t>(nearest.offsets[q])] == want.indices[static_cast<std::size_t>(want.offsets[q])]);
            CHECK(nearest.distances[static_cast<std::size_t>(nearest.offsets[q])] == d);
          } else if (d > 1.001 * radius) {
            CHECK(nearest.count(q) == 0);
          }
        }
      }
    }
  }

  TEST_CASE("neighbors: knn with k larger than the set returns every point") {
    const Points points = randomPoints(10, 5u);
    const NeighborIndex index(points);
    const NeighborLists got = index.knnSearch(points, 1000);
    REQUIRE(got.queries() == 10);
    for (std::size_t q = 0; q < 10; ++q) CHECK(got.count(q) == 10);
    requireSameLists(got, bruteForce(points, points, std::numeric_limits<double>::infinity(), 0));
  }

  TEST_CASE("neighbors: empty point sets and empty queries") {
    const NeighborIndex empty{Points(0, 3)};
    CHECK(empty.size() == 0);
    const Points queries = randomPoints(5, 1u);
    for (const NeighborLists& lists :
         {empty.radiusSearch(queries, 0.5), empty.knnSearch(queries, 3)}) {
      CHECK(lists.queries() == 5);
      CHECK(lists.offsets == std::vector<std::int64_t>(6, 0));
      CHECK(lists.indices.empty());
      CHECK(lists.distances.empty());
    }
    const NeighborIndex index(queries);
    for (const NeighborLists& lists :
         {index.radiusSearch(Points(0, 3), 0.5), index.knnSearch(Points(0, 3), 3)}) {
      CHECK(lists.queries() == 0);
      CHECK(lists.offsets == std::vector<std::int64_t>{0});
    }
  }

  TEST_CASE("neighbors: a moved index keeps answering") {
    const Points points = randomPoints(50, 2u);
    NeighborIndex first(points);
    NeighborIndex second(std::move(first));
    CHECK(second.size() == 50);
    requireSameLists(second.radiusSearch(points, 0.3), bruteForce(points, points, 0.3, 0));
    NeighborIndex third{Points(0, 3)};
    third = std::move(second);
    CHECK(third.size() == 50);
    CHECK(third.knnSearch(points, 3).indices.size() == 150);
  }

  TEST_CASE("neighbors: invalid arguments throw InvalidArgument") {
    Points points = randomPoints(20, 4u);
    points(13, 1) = std::numeric_limits<double>::quiet_NaN();
    try {
      const NeighborIndex index(points);
      FAIL("a NaN coordinate was accepted");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("row 13") != std::string::npos);
    }
    points(13, 1) = 0.5;
    points(4, 2) = -std::numeric_limits<double>::infinity();
    CHECK_THROWS_AS(NeighborIndex{points}, InvalidArgument);
    points(4, 2) = 0.5;

    const NeighborIndex index(points);
    Points queries = randomPoints(8, 6u);
    queries(6, 0) = std::numeric_limits<double>::infinity();
    try {
      (void)index.radiusSearch(queries, 0.1);
      FAIL("an infinite query was accepted");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("row 6") != std::string::npos);
    }
    CHECK_THROWS_AS((void)index.knnSearch(queries, 2), InvalidArgument);
    queries(6, 0) = 0.0;
    for (double radius : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::infinity()}) {
      CAPTURE(radius);
      CHECK_THROWS_AS((void)index.radiusSearch(queries, radius), InvalidArgument);
    }
    CHECK_THROWS_AS((void)index.knnSearch(queries, 0), InvalidArgument);
    CHECK_THROWS_AS((void)index.knnSearch(queries, -3), InvalidArgument);
    const NeighborIndex empty{Points(0, 3)};
    CHECK_THROWS_AS((void)empty.radiusSearch(queries, -1.0), InvalidArgument);
    CHECK_THROWS_AS((void)empty.knnSearch(queries, 0), InvalidArgument);
  }

  TEST_CASE("neighbors: an interrupter is polled during a search and stops it with Cancelled") {
    // A counting interrupter that says stop from its `stopAt`-th poll on (0: never).
    class Counting final : public duplexfit::Interrupter {
     public:
      explicit Counting(int stopAt) : stopAt_(stopAt) {}
      bool wasInterrupted(int) override { return ++polls == stopAt_ || (stopAt_ > 0 && polls > stopAt_); }
      int polls = 0;

     private:
      int stopAt_;
    };
    const Points points = randomPoints(20000, 21u);
    const Points queries = randomPoints(50000, 22u);
    const NeighborIndex index(points);
    // Not interrupted: polled at least once (when the search starts), and the lists are those of a search
    // without an interrupter.
    Counting never(0);
    const NeighborLists plain = index.knnSearch(queries, 3);
    const NeighborLists polled = index.knnSearch(queries, 3, &never);
    CHECK(never.polls >= 1);
    CHECK(polled.offsets == plain.offsets);
    CHECK(polled.indices == plain.indices);
    Counting neverRadius(0);
    const NeighborLists radiusPolled = index.radiusSearch(queries, 0.02, &neverRadius);
    CHECK(neverRadius.polls >= 1);
    CHECK(radiusPolled.indices == index.radiusSearch(queries, 0.02).indices);
    // Interrupted at the first poll: no result, Cancelled naming the search.
    Counting first(1);
    CHECK_THROWS_WITH_AS((void)index.knnSearch(queries, 3, &first), doctest::Contains("neighbour search"),
                         duplexfit::Cancelled);
    CHECK(first.polls == 1);
    Counting firstRadius(1);
    CHECK_THROWS_AS((void)index.radiusSearch(queries, 0.02, &firstRadius), duplexfit::Cancelled);
    // The index stays usable after a cancelled search.
    const NeighborLists again = index.knnSearch(queries, 3);
    CHECK(again.indices == plain.indices);
    // An interrupter that throws: its exception comes out of the search.
    class Throwing final : public duplexfit::Interrupter {
     public:
      bool wasInterrupted(int) override { throw std::runtime_error("interrupter failed"); }
    };
    Throwing throwing;
    CHECK_THROWS_WITH_AS((void)index.knnSearch(queries, 3, &throwing), "interrupter failed", std::runtime_error);
  }
}
