// CellGrid::within (the level assembly's and the merge's radius search, spatial/cell_grid.hpp) against the
// k-d tree's radiusSearch: the same points at the same distances, bit for bit, for radii below, at and
// above the cell, queries inside and far outside the box, duplicates and points on cell boundaries; and
// the table's size limit and bad arguments.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"
#include "spatial/cell_grid.hpp"

namespace {

using duplexfit::Index;
using duplexfit::Points;
using duplexfit::detail::CellGrid;

/// Mismatching queries between the grid and the tree for `radius`.
int mismatches(const Points& points, const Points& queries, double cell, double radius) {
  const CellGrid grid(points, cell);
  REQUIRE(grid.usable());
  const duplexfit::NeighborLists ref = duplexfit::NeighborIndex(points).radiusSearch(queries, radius);
  int bad = 0;
  for (Eigen::Index i = 0; i < queries.rows(); ++i) {
    std::vector<std::pair<Index, double>> got, want;
    const double q[3] = {queries(i, 0), queries(i, 1), queries(i, 2)};
    grid.within(q, radius, [&got](Index j, double d) { got.emplace_back(j, d); });
    // collect() (the assembly's branch-free form): the same hits in the same order, squared distances
    // whose square roots are within()'s distances.
    duplexfit::detail::ScratchVector<CellGrid::Hit> hits(3);  // written from slot 1 on: slot 0 must stay untouched
    hits[0] = CellGrid::Hit{-7, -1.0};
    const std::size_t n = grid.collect(q, radius, hits, 1);
    bool same = n == got.size() && hits[0].id == -7 && hits[0].squared == -1.0;
    for (std::size_t k = 0; same && k < n; ++k) {
      same = hits[k + 1].id == got[k].first && std::sqrt(hits[k + 1].squared) == got[k].second;
    }
    bad += same ? 0 : 1;
    const auto u = static_cast<std::size_t>(i);
    for (auto e = ref.offsets[u]; e < ref.offsets[u + 1]; ++e) {
      want.emplace_back(ref.indices[static_cast<std::size_t>(e)], ref.distances[static_cast<std::size_t>(e)]);
    }
    std::sort(got.begin(), got.end());
    std::sort(want.begin(), want.end());
    bad += got == want ? 0 : 1;
  }
  return bad;
}

}  // namespace

TEST_SUITE("spatial") {
  TEST_CASE("cell grid: the same neighbours and distances as the k-d tree's radius search") {
    std::mt19937 rng(5);
    std::normal_distribution<double> g(0.0, 1.0);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    // A sampled sphere of radius 0.5, some duplicates, and a lattice of points on cell boundaries.
    const double cell = 0.05;
    Points p(4000 + 100 + 125, 3);
    for (Eigen::Index i = 0; i < 4000; ++i) {
      Eigen::RowVector3d x(g(rng), g(rng), g(rng));
      p.row(i) = 0.5 * x.normalized();
    }
    for (Eigen::Index i = 0; i < 100; ++i) p.row(4000 + i) = p.row(13 * i);
    for (Eigen::Index i = 0; i < 125; ++i) {
      p.row(4100 + i) << cell * static_cast<double>(i % 5 - 2), cell * static_cast<double>((i / 5) % 5 - 2),
          cell * static_cast<double>(i / 25 - 2);
    }
    // Queries: the points themselves, random ones in and beyond the box, far away.
    Points q(p.rows() + 500, 3);
    q.topRows(p.rows()) = p;
    for (Eigen::Index i = 0; i < 499; ++i) q.row(p.rows() + i) << 0.7 * u(rng), 0.7 * u(rng), 0.7 * u(rng);
    q.row(q.rows() - 1) << 30.0, -30.0, 4.0;
    for (const double radius : {0.0005, cell / 2, cell, 1.7 * cell, 0.6}) {
      CAPTURE(radius);
      CHECK(mismatches(p, q, cell, radius) == 0);
    }
  }

  TEST_CASE("cell grid: points a few roundings from the radius, where the squared distance cannot decide") {
    // Points at r·(1 + k·2⁻⁵²) from the origin along each axis and diagonal, k = −8 … 8, for radii that
    // do and do not square exactly: a hit is exactly a distance (square root rounded) below r, as in the tree.
    for (const double radius : {0.05, 0.1, 1.0 / 3.0, 0.7071067811865476, 2.0}) {
      CAPTURE(radius);
      Points p(17 * 4, 3);
      const Eigen::RowVector3d dirs[4] = {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}, Eigen::RowVector3d(1, 1, 1).normalized()};
      for (int k = -8; k <= 8; ++k) {
        for (int d = 0; d < 4; ++d) {
          p.row((k + 8) * 4 + d) = radius * (1.0 + k * std::ldexp(1.0, -52)) * dirs[d];
        }
      }
      Points q = Points::Zero(1, 3);
      for (const double cell : {radius, radius / 3}) CHECK(mismatches(p, q, cell, radius) == 0);
    }
  }

  TEST_CASE("cell grid: empty and single-point sets, the size limit, bad arguments") {
    const Points none(0, 3);
    const CellGrid empty(none, 0.1);
    CHECK(empty.usable());
    CHECK(empty.size() == 0);
    const double q[3] = {0.0, 0.0, 0.0};
    int hits = 0;
    empty.within(q, 1.0, [&hits](Index, double) { ++hits; });
    CHECK(hits == 0);
    Points one(1, 3);
    one << 0.25, 0.0, 0.0;
    const CellGrid single(one, 0.1);
    single.within(q, 0.3, [&hits](Index j, double d) {
      ++hits;
      CHECK(j == 0);
      CHECK(d == 0.25);
    });
    single.within(q, 0.25, [&hits](Index, double) { ++hits; });  // strict: at the radius is not within
    CHECK(hits == 1);
    Points wide(2, 3);
    wide << 0.0, 0.0, 0.0, 10.0, 10.0, 10.0;
    CHECK_FALSE(CellGrid(wide, 0.01).usable());  // 1001^3 cells
    CHECK(CellGrid(wide, 1.0).usable());
    CHECK_THROWS_AS(CellGrid(wide, 0.0), duplexfit::InvalidArgument);
    CHECK_THROWS_AS(CellGrid(wide, std::nan("")), duplexfit::InvalidArgument);
    wide(1, 2) = std::nan("");
    CHECK_THROWS_AS(CellGrid(wide, 1.0), duplexfit::InvalidArgument);
  }
}
