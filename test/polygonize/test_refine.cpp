// Local refinement of the marching grid (lib/polygonize/refine.cpp): the bisected Kuhn tetrahedra
// tile their cells and, with the unrefined cells around them, form a conforming mesh (every interior
// face shared by exactly two tetrahedra); polygonize with refined cells stays closed and manifold,
// matches between adaptive and full sampling, and follows a plate about one node thick that the plain
// grid contours more than a third of a cell away from the surface.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/polygonize.hpp"
#include "polygonize/mesh_checks.hpp"
#include "polygonize/node_store.hpp"
#include "polygonize/refine.hpp"

namespace {

using duplexfit::FieldSampler;
using duplexfit::GridSpec;
using duplexfit::Mesh;
using duplexfit::Points;
using duplexfit::polygonize;
using duplexfit::PolygonizeOptions;
using duplexfit::PolygonizeResult;
using duplexfit::detail::FineTet;
using duplexfit::detail::RefinedRegion;
using duplexfit::detail::refineCells;
using duplexfit::testing::polygonize::identical;
using duplexfit::testing::polygonize::sortedTriangles;
using duplexfit::testing::polygonize::topology;
using duplexfit::testing::polygonize::Topology;
using Field = std::function<double(const Eigen::Vector3d&)>;
using P3 = std::array<std::int32_t, 3>;
using Face = std::array<P3, 3>;

FieldSampler samplerOf(Field field) {
  return [field = std::move(field)](const Points& q, Eigen::VectorXd& values) {
    values.resize(q.rows());
    for (Eigen::Index r = 0; r < q.rows(); ++r) values(r) = field(q.row(r).transpose());
  };
}

std::int64_t det6(const FineTet& t) {
  std::int64_t a[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      a[r][c] = std::int64_t{t.x[static_cast<std::size_t>(r + 1)][static_cast<std::size_t>(c)]} -
                t.x[0][static_cast<std::size_t>(c)];
    }
  }
  return a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
         a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
}

void addFaces(const FineTet& t, std::map<Face, int>& faces) {
  for (int skip = 0; skip < 4; ++skip) {
    Face f{};
    int n = 0;
    for (int v = 0; v < 4; ++v) {
      if (v != skip) f[static_cast<std::size_t>(n++)] = t.x[static_cast<std::size_t>(v)];
    }
    std::sort(f.begin(), f.end());
    ++faces[f];
  }
}

/// Faces on the grid's outer boundary (all three corners on one bounding plane).
bool onGridBoundary(const Face& f, const Eigen::Vector3i& cells, std::int32_t factor) {
  for (int a = 0; a < 3; ++a) {
    for (const std::int32_t plane : {0, factor * cells(a)}) {
      bool all = true;
      for (const P3& p : f) all = all && p[static_cast<std::size_t>(a)] == plane;
      if (all) return true;
    }
  }
  return false;
}

/// Signed distance of a disc-shaped plate (half-thickness t, radius r) through centre c with unit
/// normal n, positive inside.
Field plate(const Eigen::Vector3d& c, const Eigen::Vector3d& n, double t, double r) {
  return [=](const Eigen::Vector3d& x) {
    const Eigen::Vector3d d = x - c;
    const double along = d.dot(n);
    const double radial = (d - along * n).norm();
    return -std::max(std::abs(along) - t, radial - r);
  };
}

/// Largest |f| at the face centres (f is a distance, so this bounds their distance to the surface).
double centreDeviation(const Mesh& m, const Field& f) {
  double worst = 0.0;
  for (Eigen::Index i = 0; i < m.faces.rows(); ++i) {
    const Eigen::Vector3d c = (m.vertices.row(m.faces(i, 0)) + m.vertices.row(m.faces(i, 1)) +
                               m.vertices.row(m.faces(i, 2))).transpose() / 3.0;
    worst = std::max(worst, std::abs(f(c)));
  }
  return worst;
}

}  // namespace

TEST_SUITE("polygonize") {
  TEST_CASE("polygonize: slabs welded by vertex key are the whole grid's meshes, refined cells included") {
    GridSpec g;
    g.box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
    g.cells = Eigen::Vector3i::Constant(40);
    const double h = g.cellSize()(0);
    // A plate about one node thick tilted across every slab (refined cells on both sides of each cut) and a
    // ball, at two levels.
    const Field thin = plate(Eigen::Vector3d(0.013, -0.021, 0.007), Eigen::Vector3d(0.3, 0.5, 0.81).normalized(), 0.6 * h, 0.7);
    const Field ball = [](const Eigen::Vector3d& x) { return 0.55 - (x - Eigen::Vector3d(0.03, -0.02, 0.01)).norm(); };
    for (const bool adaptive : {true, false}) {
      for (const auto& [name, field, isos] : {std::tuple<const char*, Field, std::vector<double>>{"plate", thin, {0.0}},
                                              {"ball", ball, {0.0, 0.1}}}) {
        CAPTURE(name);
        CAPTURE(adaptive);
        PolygonizeOptions whole;
        whole.adaptive = adaptive;
        whole.refineLevels = 2;
        whole.keepVertexKeys = true;
        const PolygonizeResult all = polygonize(samplerOf(field), g, isos, whole);
        REQUIRE(all.vertexKeys.size() == isos.size());
        if (std::string(name) == "plate") CHECK(all.stats.refinedCells > 0);
        // Cuts that are not block-aligned, and one slab thinner than the halo.
        const std::vector<int> cuts = {0, 11, 17, 29, 40};
        std::vector<PolygonizeResult> parts;
        for (std::size_t s = 0; s + 1 < cuts.size(); ++s) {
          PolygonizeOptions o = whole;
          o.keepVertexKeys = false;
          o.slabBegin = cuts[s];
          o.slabEnd = cuts[s + 1];
          parts.push_back(polygonize(samplerOf(field), g, isos, o));
          REQUIRE(parts.back().vertexKeys.size() == isos.size());
        }
        for (std::size_t q = 0; q < isos.size(); ++q) {
          CAPTURE(q);
          std::vector<const Mesh*> pieces;
          std::vector<const std::vector<std::uint64_t>*> keys;
          for (const PolygonizeResult& r : parts) {
            pieces.push_back(&r.meshes[q]);
            keys.push_back(&r.vertexKeys[q]);
          }
          const Mesh welded = duplexfit::weldByKeys(pieces, keys);
          CHECK(welded.vertices.rows() == all.meshes[q].vertices.rows());
          CHECK(welded.faces.rows() == all.meshes[q].faces.rows());
          CHECK(sortedTriangles(welded) == sortedTriangles(all.meshes[q]));
          const Topology t = topology(welded);
          CHECK(t.closedManifold());
          CHECK(t.components == 1);
        }
      }
    }
    PolygonizeOptions bad;
    bad.slabBegin = 10;
    bad.slabEnd = 10;
    CHECK_THROWS_AS(polygonize(samplerOf(ball), g, {0.0}, bad), duplexfit::InvalidArgument);
    bad.slabEnd = 41;
    CHECK_THROWS_AS(polygonize(samplerOf(ball), g, {0.0}, bad), duplexfit::InvalidArgument);
  }

  TEST_CASE("refineCells: bisected tetrahedra tile their cells and the whole grid stays conforming") {
    const Eigen::Vector3i cells(7, 6, 5);
    const std::vector<std::array<int, 3>> seeds = {{1, 1, 1}, {4, 3, 2}, {6, 5, 4}, {0, 5, 0}};
    // With deeper seeds (PolygonizeOptions::refineDeeperCells) too: one level more there, the same closure.
    const std::vector<std::array<int, 3>> deep = {{2, 1, 1}, {5, 0, 4}};
    for (int levels : {1, 2}) {
      for (int dilation : {0, 1}) {
       for (const bool deeper : {false, true}) {
        CAPTURE(levels);
        CAPTURE(dilation);
        CAPTURE(deeper);
        const RefinedRegion r = refineCells(cells, seeds, levels, dilation, 1 << 20,
                                            deeper ? deep : std::vector<std::array<int, 3>>{});
        REQUIRE(!r.empty());
        CHECK(r.factor == (1 << (levels + (deeper ? 1 : 0))));
        if (deeper) {
          // A deep seed's tetrahedra are 8 times smaller than a seed's.
          for (const auto& s : deep) {
            const std::int64_t id = s[0] + std::int64_t{cells(0)} * (s[1] + std::int64_t{cells(1)} * s[2]);
            REQUIRE(r.contains(id));
            const std::size_t c = static_cast<std::size_t>(std::lower_bound(r.cells.begin(), r.cells.end(), id) - r.cells.begin());
            CHECK(r.offsets[c + 1] - r.offsets[c] >= static_cast<std::size_t>(6 * r.factor * r.factor * r.factor));
          }
        }
        CHECK(r.cells.size() + 1 == r.offsets.size());
        CHECK(std::is_sorted(r.cells.begin(), r.cells.end()));
        const std::int64_t cellVolume6 = 6 * std::int64_t{r.factor} * r.factor * r.factor;
        std::map<Face, int> faces;
        for (std::size_t c = 0; c < r.cells.size(); ++c) {
          std::int64_t volume6 = 0;
          for (std::size_t t = r.offsets[c]; t < r.offsets[c + 1]; ++t) {
            CHECK(det6(r.tets[t]) != 0);
            volume6 += std::abs(det6(r.tets[t]));
            addFaces(r.tets[t], faces);
          }
          CHECK(volume6 == cellVolume6);  // no overlap, no gap inside the cell
        }
        // Seeds are refined fully: tetrahedra of cells 2^levels times smaller.
        const std::size_t seedTets = static_cast<std::size_t>(6) << (3 * levels);
        for (const auto& s : seeds) {
          const std::int64_t id = s[0] + std::int64_t{cells(0)} * (s[1] + std::int64_t{cells(1)} * s[2]);
          REQUIRE(r.contains(id));
          const std::size_t c = static_cast<std::size_t>(
              std::lower_bound(r.cells.begin(), r.cells.end(), id) - r.cells.begin());
          CHECK(r.offsets[c + 1] - r.offsets[c] >= seedTets);
        }
        // The other cells of the grid, unrefined.
        for (int k = 0; k < cells(2); ++k) {
          for (int j = 0; j < cells(1); ++j) {
            for (int i = 0; i < cells(0); ++i) {
              if (r.contains(i + std::int64_t{cells(0)} * (j + std::int64_t{cells(1)} * k))) continue;
              std::vector<FineTet> plain;
              duplexfit::detail::kuhnTets({i, j, k}, r.factor, plain);
              for (const FineTet& t : plain) addFaces(t, faces);
            }
          }
        }
        std::int64_t bad = 0;
        for (const auto& [face, count] : faces) {
          const int expected = onGridBoundary(face, cells, r.factor) ? 1 : 2;
          if (count != expected) ++bad;
        }
        CHECK(bad == 0);
       }
      }
    }
    // Too many cells: nothing is refined.
    const RefinedRegion capped = refineCells(cells, seeds, 2, 1, 10);
    CHECK(capped.empty());
    CHECK(capped.skipped);
  }

  TEST_CASE("refineCells: two slabs on two threads give the region of one") {
    // A shell of seed cells (above the two-slab threshold of 2,048), a few of them deeper, split where the
    // seeds' work halves: the same cells, tetrahedra (corners, tags, depths) and counts as in one piece.
    const Eigen::Vector3i cells(34, 32, 30);
    std::vector<std::array<int, 3>> seeds, deep;
    for (int k = 0; k < cells(2); ++k) {
      for (int j = 0; j < cells(1); ++j) {
        for (int i = 0; i < cells(0); ++i) {
          const double r = std::sqrt((i - 16.5) * (i - 16.5) + (j - 15.7) * (j - 15.7) + (k - 14.2) * (k - 14.2));
          if (std::abs(r - 12.0) < 0.75) seeds.push_back({i, j, k});
          if (std::abs(r - 12.0) < 0.75 && i == 16) deep.push_back({i, j, k});
        }
      }
    }
    REQUIRE(seeds.size() >= 2048);
    for (const bool deeper : {false, true}) {
      CAPTURE(deeper);
      const std::vector<std::array<int, 3>>& d = deeper ? deep : std::vector<std::array<int, 3>>{};
      const RefinedRegion one = refineCells(cells, seeds, 1, 1, 1 << 20, d, 1);
      const RefinedRegion two = refineCells(cells, seeds, 1, 1, 1 << 20, d, 2);
      CHECK(two.levels == one.levels);
      CHECK(two.factor == one.factor);
      CHECK(two.seeds == one.seeds);
      CHECK(two.cells == one.cells);
      CHECK(two.offsets == one.offsets);
      REQUIRE(two.tets.size() == one.tets.size());
      std::size_t differ = 0;
      for (std::size_t t = 0; t < one.tets.size(); ++t) {
        differ += one.tets[t].x == two.tets[t].x && one.tets[t].tag == two.tets[t].tag &&
                          one.tets[t].depth == two.tets[t].depth
                      ? 0
                      : 1;
      }
      CHECK(differ == 0);
      // The seed cap holds for the two slabs together.
      const RefinedRegion capped = refineCells(cells, seeds, 1, 1, static_cast<std::int64_t>(one.seeds) - 1, d, 2);
      CHECK(capped.skipped);
      CHECK(capped.empty());
      CHECK(capped.seeds == one.seeds);
    }
  }

  TEST_CASE("polygonize: refined cells keep the meshes closed, and adaptive equals full sampling") {
    GridSpec g;
    g.box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
    g.cells = Eigen::Vector3i::Constant(24);
    const Field ball = [](const Eigen::Vector3d& x) { return 0.55 - (x - Eigen::Vector3d(0.03, -0.02, 0.01)).norm(); };
    PolygonizeOptions plain, refined;
    refined.refineLevels = 2;
    refined.refineThin = false;
    // Cells on the sphere (and a few away from it, which contribute nothing).
    for (int i = 0; i < 24; i += 3) refined.refineCells.push_back({i, 12, 12});
    refined.refineCells.push_back({12, 12, 18});
    refined.refineCells.push_back({5, 19, 12});
    const std::vector<double> isos = {0.0, 0.1};
    const PolygonizeResult a = polygonize(samplerOf(ball), g, isos, plain);
    const PolygonizeResult b = polygonize(samplerOf(ball), g, isos, refined);
    PolygonizeOptions refinedFull = refined;
    refinedFull.adaptive = false;
    const PolygonizeResult c = polygonize(samplerOf(ball), g, isos, refinedFull);
    CHECK(b.stats.refinedCells > static_cast<std::int64_t>(refined.refineCells.size()));
    CHECK(b.stats.refinedEvaluations > 0);
    for (std::size_t q = 0; q < isos.size(); ++q) {
      CAPTURE(q);
      const Topology t = topology(b.meshes[q]);
      CHECK(t.closedManifold());
      CHECK(t.components == 1);
      CHECK(t.euler == 2);
      CHECK(b.meshes[q].faces.rows() > a.meshes[q].faces.rows());
      CHECK(identical(b.meshes[q], c.meshes[q]));
      // Vertices on the refined tetrahedra's edges are still on the sphere (linear interpolation of a
      // distance field, exact along radial lines and close elsewhere).
      double worst = 0.0;
      for (Eigen::Index v = 0; v < b.meshes[q].vertices.rows(); ++v) {
        worst = std::max(worst, std::abs(ball(b.meshes[q].vertices.row(v).transpose()) - isos[q]));
      }
      CHECK(worst < 0.02);
    }
  }

  TEST_CASE("polygonize: a tilted plate about one node thick is followed by the refinement") {
    GridSpec g;
    g.box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
    g.cells = Eigen::Vector3i::Constant(32);
    const double h = g.cellSize()(0);
    const Field f = plate(Eigen::Vector3d(0.013, -0.021, 0.007), Eigen::Vector3d(0.3, 0.2, 0.93).normalized(),
                          0.6 * h, 0.6);
    PolygonizeOptions plain, all;
    all.refineLevels = 2;
    const PolygonizeResult a = polygonize(samplerOf(f), g, {0.0}, plain);
    const PolygonizeResult b = polygonize(samplerOf(f), g, {0.0}, all);
    CHECK(a.stats.thinCells == 0);
    CHECK(b.stats.thinCells > 0);
    CHECK(!b.stats.refinementSkipped);
    const Topology t = topology(b.meshes[0]);
    CHECK(t.closedManifold());
    CHECK(t.components == 1);
    CHECK(t.euler == 2);
    const double before = centreDeviation(a.meshes[0], f), after = centreDeviation(b.meshes[0], f);
    INFO("face-centre deviation / h: plain " << before / h << ", refined " << after / h);
    CHECK(before > 0.3 * h);
    CHECK(after < 0.5 * before);
    CHECK(b.stats.deviatingCells == b.stats.thinCells);  // no tolerance: every thin cell is a seed
    // With a tolerance, only the thin cells whose contour is off by more are refined (the plate's flat
    // middle, where the plain contour is already close, is left) and the worst face still improves.
    PolygonizeOptions tolerant = all;
    tolerant.refineTolerance = 0.25 * h;
    const PolygonizeResult c = polygonize(samplerOf(f), g, {0.0}, tolerant);
    INFO("thin " << c.stats.thinCells << ", deviating " << c.stats.deviatingCells);
    CHECK(c.stats.deviatingCells > 0);
    CHECK(c.stats.deviatingCells < c.stats.thinCells);
    CHECK(c.meshes[0].faces.rows() < b.meshes[0].faces.rows());
    CHECK(topology(c.meshes[0]).closedManifold());
    CHECK(centreDeviation(c.meshes[0], f) < 0.5 * before);
    // Refined as needed (the default): the deviating cells whose contour one level less is already within
    // the tolerance stay there, with no ring; against every deviating cell refined fully, fewer tetrahedra for
    // the same closed plate, and every face centre still within the tolerance of the sharper run's worst.
    PolygonizeOptions everyFully = tolerant;
    everyFully.refineAsNeeded = false;
    const PolygonizeResult d = polygonize(samplerOf(f), g, {0.0}, everyFully);
    INFO("shallow " << c.stats.shallowCells << " of " << c.stats.deviatingCells << ", tetrahedra " << c.stats.refinedTetrahedra
                    << " against " << d.stats.refinedTetrahedra);
    CHECK(d.stats.shallowCells == 0);
    CHECK(d.stats.deviatingCells == c.stats.deviatingCells);
    CHECK(c.stats.shallowCells > 0);
    CHECK(c.stats.shallowCells < c.stats.deviatingCells);
    CHECK(c.stats.refinedTetrahedra < d.stats.refinedTetrahedra);
    const Topology td = topology(d.meshes[0]), tc = topology(c.meshes[0]);
    CHECK(tc.components == td.components);
    CHECK(tc.euler == td.euler);
    CHECK(centreDeviation(c.meshes[0], f) <= centreDeviation(d.meshes[0], f) + tolerant.refineTolerance);
  }

  TEST_CASE("refinedDeviatingCells: a plane's contour is exact one level less, a small ball's is not; the values "
            "evaluated are kept on the finer lattice") {
    GridSpec g;
    g.box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d::Constant(1.0));
    g.cells = Eigen::Vector3i::Constant(8);
    const double h = g.cellSize()(0);
    duplexfit::detail::NodeStore store(g.cells, 4);  // nothing sampled: every lattice point is evaluated
    const std::vector<std::array<int, 3>> candidates = {{3, 3, 3}, {4, 3, 3}, {3, 4, 4}};
    const RefinedRegion region = refineCells(g.cells, candidates, 1, 0, 1000);
    REQUIRE(region.factor == 2);
    const Field plane = [](const Eigen::Vector3d& x) { return 0.3 * x(0) - 0.5 * x(1) + 0.8 * x(2) + 0.02; };
    duplexfit::PolygonizeStats stats;
    std::vector<std::uint64_t> keys;
    std::vector<float> values;
    const auto exact = duplexfit::detail::refinedDeviatingCells(region, candidates, store, g, 0.0, samplerOf(plane), 1e-9,
                                                                 64, stats, 4, keys, values);
    CHECK(exact.empty());  // linear interpolation of a linear field is exact
    CHECK(stats.refinedEvaluations > 0);
    REQUIRE(keys.size() == values.size());
    REQUIRE(!keys.empty());
    // Each kept value is the field at its point of the lattice four times finer than the grid.
    const std::uint64_t mask = (std::uint64_t{1} << 21) - 1;
    for (std::size_t i = 0; i < keys.size(); ++i) {
      const Eigen::Vector3d p = g.box.min() + 0.25 * h *
                                                  Eigen::Vector3d(static_cast<double>(keys[i] & mask),
                                                                  static_cast<double>((keys[i] >> 21) & mask),
                                                                  static_cast<double>(keys[i] >> 42));
      CAPTURE(i);
      CHECK(static_cast<double>(values[i]) == doctest::Approx(plane(p)).epsilon(1e-6));
    }
    // A ball of radius 0.1 inside cell (3, 3, 3) curves there: its contour one level less is off by more than
    // 1e-4 of the field; the candidates it does not reach have no contour; one outside the region deviates.
    const Field ball = [](const Eigen::Vector3d& x) { return 0.1 - (x - Eigen::Vector3d(-0.12, -0.13, -0.11)).norm(); };
    std::vector<std::array<int, 3>> more = candidates;
    more.push_back({0, 0, 0});
    keys.clear();
    values.clear();
    std::vector<std::array<int, 3>> within;
    const auto curved = duplexfit::detail::refinedDeviatingCells(region, more, store, g, 0.0, samplerOf(ball), 1e-4, 64,
                                                                  stats, 4, keys, values, &within);
    CHECK(curved == std::vector<std::array<int, 3>>{{3, 3, 3}, {0, 0, 0}});
    CHECK(within.size() + curved.size() == more.size());  // the others, the partition's second part
    for (const auto& c : within) CHECK(std::find(curved.begin(), curved.end(), c) == curved.end());
    // A plate 0.4 h thick centred on the middle lattice plane of cell (3, 3, 3) (z = −h/2) is one finer
    // lattice point thick there: refined further whatever the tolerance; a plate 1.2 h thick centred on the
    // cell's lower face is not, and its contour in the cell (where f is linear) is exact.
    const auto slab = [](double centre, double halfThickness) {
      return Field([=](const Eigen::Vector3d& x) { return halfThickness - std::abs(x(2) - centre); });
    };
    const std::vector<std::array<int, 3>> one = {{3, 3, 3}};
    CHECK(duplexfit::detail::refinedDeviatingCells(region, one, store, g, 0.0, samplerOf(slab(-0.5 * h, 0.2 * h)), 10.0, 64,
                                                   stats, 4, keys, values) == one);
    CHECK(duplexfit::detail::refinedDeviatingCells(region, one, store, g, 0.0, samplerOf(slab(-h, 0.6 * h)), 1e-9, 64,
                                                   stats, 4, keys, values)
              .empty());
  }
}
