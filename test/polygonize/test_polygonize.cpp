// polygonize() on analytic fields: closed, manifold, oriented meshes with the right topology, area
// and volume; adaptive sampling equal to full sampling (a thin extra sheet included) at a fraction
// of the nodes; several iso values per pass; random fields with exact hits; argument errors;
// timing.
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "support/recording_interrupter.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/polygonize.hpp"
#include "polygonize/mesh_checks.hpp"

namespace {

using duplexfit::Cancelled;
using duplexfit::FieldSampler;
using duplexfit::GridSpec;
using duplexfit::InvalidArgument;
using duplexfit::Mesh;
using duplexfit::Points;
using duplexfit::polygonize;
using duplexfit::PolygonizeOptions;
using duplexfit::PolygonizeResult;
using duplexfit::testing::polygonize::area;
using duplexfit::testing::polygonize::identical;
using duplexfit::testing::polygonize::topology;
using duplexfit::testing::polygonize::Topology;
using duplexfit::testing::polygonize::volume;
using Field = std::function<double(const Eigen::Vector3d&)>;

constexpr double kPi = 3.14159265358979323846;

FieldSampler samplerOf(Field field) {
  return [field = std::move(field)](const Points& q, Eigen::VectorXd& values) {
    values.resize(q.rows());
    for (Eigen::Index r = 0; r < q.rows(); ++r) values(r) = field(q.row(r).transpose());
  };
}

/// Signed distance of a sphere, positive inside.
Field sphere(const Eigen::Vector3d& centre, double radius) {
  return [=](const Eigen::Vector3d& x) { return radius - (x - centre).norm(); };
}

/// Signed distance of a torus around z (major radius big, minor radius small), positive inside.
Field torus(double big, double small) {
  return [=](const Eigen::Vector3d& x) {
    const double rho = std::hypot(x(0), x(1)) - big;
    return small - std::hypot(rho, x(2));
  };
}

/// Union (max) of two fields.
Field unite(Field a, Field b) {
  return [=](const Eigen::Vector3d& x) { return std::max(a(x), b(x)); };
}

/// A flat cylinder ("pancake") of half-thickness t and radius r at height z0: a 1-Lipschitz field
/// that is positive only in a sheet about one cell thick.
Field pancake(double z0, double radius, double t) {
  return [=](const Eigen::Vector3d& x) {
    return -std::max(std::abs(x(2) - z0) - t, std::hypot(x(0), x(1)) - radius);
  };
}

GridSpec cube(double half, int cells) {
  GridSpec g;
  g.box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-half), Eigen::Vector3d::Constant(half));
  g.cells = Eigen::Vector3i::Constant(cells);
  return g;
}

PolygonizeOptions fullMode() {
  PolygonizeOptions o;
  o.adaptive = false;
  return o;
}

/// Faces whose corners, rounded to single precision as the mesh writers store them, are collinear
/// or coincide (the measure module's zero-area test: |ab × ac|² ≤ 1e-24 |ab|² |ac|²).
std::int64_t zeroAreaFaces(const Mesh& mesh) {
  std::int64_t count = 0;
  for (Eigen::Index f = 0; f < mesh.faces.rows(); ++f) {
    Eigen::Vector3d p[3];
    for (int c = 0; c < 3; ++c) {
      p[c] = mesh.vertices.row(mesh.faces(f, c)).transpose().cast<float>().cast<double>();
    }
    const Eigen::Vector3d ab = p[1] - p[0], ac = p[2] - p[0];
    if (ab.cross(ac).squaredNorm() <= 1e-24 * ab.squaredNorm() * ac.squaredNorm()) ++count;
  }
  return count;
}

void checkClosed(const Mesh& mesh, std::int64_t components, std::int64_t euler) {
  const Topology t = topology(mesh);
  INFO("V=" << t.vertices << " E=" << t.edges << " F=" << t.faces);
  CHECK(t.faces > 0);
  CHECK(t.boundaryEdges == 0);
  CHECK(t.nonManifoldEdges == 0);
  CHECK(t.nonManifoldVertices == 0);
  CHECK(t.inconsistentEdges == 0);
  CHECK(t.degenerateFaces == 0);
  CHECK(zeroAreaFaces(mesh) == 0);
  CHECK(t.unreferencedVertices == 0);
  CHECK(t.components == components);
  CHECK(t.euler == euler);
  CHECK(volume(mesh) > 0.0);
}

/// Largest | |v − c| − r | over the vertices.
double radialError(const Mesh& mesh, const Eigen::Vector3d& c, double r) {
  double e = 0.0;
  for (Eigen::Index v = 0; v < mesh.vertices.rows(); ++v) {
    e = std::max(e, std::abs((mesh.vertices.row(v).transpose() - c).norm() - r));
  }
  return e;
}

/// Deterministic pseudo-random value in [−1, 1] per node, quantised to multiples of 1/4 so that
/// many nodes hit the iso value 0 exactly; −1 within one cell of the box boundary.
Field randomField(const GridSpec& g, std::uint32_t seed) {
  const Eigen::Vector3d h = g.cellSize();
  return [=](const Eigen::Vector3d& x) {
    std::uint64_t idx[3];
    for (int a = 0; a < 3; ++a) {
      const double n = std::round((x(a) - g.box.min()(a)) / h(a));
      if (n < 1.5 || n > g.cells(a) - 1.5) return -1.0;
      idx[a] = static_cast<std::uint64_t>(n);
    }
    std::uint64_t s = seed ^ (idx[0] * 0x9E3779B97F4A7C15ull) ^ (idx[1] * 0xC2B2AE3D27D4EB4Full) ^
                      (idx[2] * 0x165667B19E3779F9ull);
    s ^= s >> 31;
    s *= 0xBF58476D1CE4E5B9ull;
    s ^= s >> 29;
    return static_cast<double>(static_cast<int>(s % 9) - 4) / 4.0;
  };
}

// The 512³ case takes about a minute without optimisation or under sanitizers: it is skipped by
// default there (doctest's --no-skip runs it).
#if defined(__SANITIZE_ADDRESS__)
#define DUPLEXFIT_POLYGONIZE_TEST_ASAN
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define DUPLEXFIT_POLYGONIZE_TEST_ASAN
#endif
#endif
#if defined(NDEBUG) && !defined(DUPLEXFIT_POLYGONIZE_TEST_ASAN)
constexpr bool kSlowBuild = false;
#else
constexpr bool kSlowBuild = true;
#endif
#undef DUPLEXFIT_POLYGONIZE_TEST_ASAN

}  // namespace

TEST_SUITE("polygonize") {
  TEST_CASE("polygonize: GridSpec::fromCellSize covers the box with cubic cells") {
    const Eigen::AlignedBox3d box(Eigen::Vector3d(0.0, -1.0, 2.0), Eigen::Vector3d(1.0, 0.5, 2.1));
    const GridSpec g = GridSpec::fromCellSize(box, 0.25);
    CHECK(g.cells == Eigen::Vector3i(4, 6, 1));
    CHECK(g.cellSize().isApprox(Eigen::Vector3d::Constant(0.25)));
    CHECK(g.box.contains(box));
    CHECK(g.box.center().isApprox(box.center()));
    CHECK(g.node(0, 0, 0).isApprox(g.box.min()));
    CHECK(g.node(4, 6, 1) == g.box.max());
    CHECK(g.nodeCount() == 5 * 7 * 2);
    g.validate();
  }

  TEST_CASE("polygonize: invalid grids, options and inputs throw InvalidArgument") {
    const Eigen::AlignedBox3d unit(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
    const double nan = std::nan("");
    CHECK_THROWS_AS(GridSpec::fromCellSize(unit, 0.0), InvalidArgument);
    CHECK_THROWS_AS(GridSpec::fromCellSize(unit, -0.1), InvalidArgument);
    CHECK_THROWS_AS(GridSpec::fromCellSize(unit, nan), InvalidArgument);
    CHECK_THROWS_AS(
        GridSpec::fromCellSize(
            Eigen::AlignedBox3d(Eigen::Vector3d(nan, 0, 0), Eigen::Vector3d::Ones()), 0.1),
        InvalidArgument);
    CHECK_THROWS_AS(GridSpec::fromCellSize(Eigen::AlignedBox3d(), 0.1), InvalidArgument);
    CHECK_THROWS_WITH_AS(GridSpec::fromCellSize(unit, 1e-4), doctest::Contains("exceed"),
                         InvalidArgument);

    const FieldSampler ball = samplerOf(sphere(Eigen::Vector3d::Zero(), 0.5));
    GridSpec g = cube(1.0, 8);
    g.cells(1) = 0;
    CHECK_THROWS_WITH_AS(polygonize(ball, g, {0.0}), doctest::Contains("cells(1)"),
                         InvalidArgument);
    g.cells(1) = -3;
    CHECK_THROWS_AS(polygonize(ball, g, {0.0}), InvalidArgument);
    g = cube(1.0, 8);
    g.box.max()(2) = std::numeric_limits<double>::infinity();
    CHECK_THROWS_AS(polygonize(ball, g, {0.0}), InvalidArgument);
    g = cube(1.0, 8);
    g.box.max()(0) = g.box.min()(0);
    CHECK_THROWS_AS(polygonize(ball, g, {0.0}), InvalidArgument);
    g = cube(1.0, 2000);
    CHECK_THROWS_WITH_AS(polygonize(ball, g, {0.0}), doctest::Contains("exceed"), InvalidArgument);

    g = cube(1.0, 8);
    CHECK_THROWS_WITH_AS(polygonize(ball, g, {}), doctest::Contains("empty"), InvalidArgument);
    CHECK_THROWS_AS(polygonize(ball, g, {0.0, nan}), InvalidArgument);
    CHECK_THROWS_AS(polygonize(FieldSampler(), g, {0.0}), InvalidArgument);
    PolygonizeOptions o;
    for (int step : {0, 1, 6, 128}) {
      o.coarseStep = step;
      CHECK_THROWS_WITH_AS(polygonize(ball, g, {0.0}, o), doctest::Contains("coarseStep"),
                           InvalidArgument);
    }
    o = {};
    o.lipschitz = 0.0;
    CHECK_THROWS_WITH_AS(polygonize(ball, g, {0.0}, o), doctest::Contains("lipschitz"),
                         InvalidArgument);
    o = {};
    o.batchSize = 0;
    CHECK_THROWS_AS(polygonize(ball, g, {0.0}, o), InvalidArgument);
  }

  TEST_CASE("polygonize: a sampler returning a non-finite value or a wrong count is named") {
    const GridSpec g = cube(1.0, 8);
    const FieldSampler bad = [](const Points& q, Eigen::VectorXd& v) {
      v.resize(q.rows());
      for (Eigen::Index r = 0; r < q.rows(); ++r) {
        const bool hit = q(r, 0) == 0.0 && q(r, 1) == -0.5 && q(r, 2) == 1.0;
        v(r) = hit ? std::nan("") : 0.5 - q.row(r).norm();
      }
    };
    for (bool adaptive : {true, false}) {
      PolygonizeOptions o;
      o.adaptive = adaptive;
      o.coarseStep = 2;  // so the coarse lattice contains that node
      CHECK_THROWS_WITH_AS(polygonize(bad, g, {0.0}, o),
                           doctest::Contains("grid node (4, 2, 8), position (0, -0.5, 1)"),
                           InvalidArgument);
    }
    const FieldSampler short_ = [](const Points& q, Eigen::VectorXd& v) {
      v = Eigen::VectorXd::Zero(q.rows() - 1);
    };
    CHECK_THROWS_WITH_AS(polygonize(short_, g, {0.0}), doctest::Contains("values for"),
                         InvalidArgument);
  }

  TEST_CASE("polygonize: a sphere is closed, manifold, outward, with χ = 2 and the right area") {
    const double r = 0.7;
    const Eigen::Vector3d c(0.013, -0.021, 0.007);
    for (int cells : {32, 128}) {
      CAPTURE(cells);
      const GridSpec g = cube(1.0, cells);
      const double h = g.cellSize()(0);
      for (bool adaptive : {true, false}) {
        if (!adaptive && cells > 32) continue;  // the full mode is compared on finer grids below
        CAPTURE(adaptive);
        PolygonizeOptions o;
        o.adaptive = adaptive;
        const PolygonizeResult res = polygonize(samplerOf(sphere(c, r)), g, {0.0}, o);
        REQUIRE(res.meshes.size() == 1);
        const Mesh& m = res.meshes[0];
        checkClosed(m, 1, 2);
        CHECK(radialError(m, c, r) < h * h / r);
        const double a = area(m), exact = 4.0 * kPi * r * r;
        // Linear interpolation of a distance field: O(h²) errors, 0.2 % at 32³ and 0.013 % at 128³.
        CHECK(std::abs(a - exact) / exact < (cells >= 128 ? 0.001 : 0.01));
        CHECK(std::abs(volume(m) - 4.0 / 3.0 * kPi * r * r * r) / (4.0 / 3.0 * kPi * r * r * r) <
              (cells >= 128 ? 0.001 : 0.01));
        if (!adaptive) CHECK(res.stats.evaluatedNodes == g.nodeCount());
      }
    }
  }

  TEST_CASE("polygonize: node values exactly on the iso value still give a closed manifold") {
    // r = 0.5 on a grid with h = 1/16: many nodes (and whole node rows) have f == 0 exactly.
    const GridSpec g = cube(1.0, 32);
    for (bool adaptive : {true, false}) {
      PolygonizeOptions o;
      o.adaptive = adaptive;
      const Mesh m =
          polygonize(samplerOf(sphere(Eigen::Vector3d::Zero(), 0.5)), g, {0.0}, o).meshes.front();
      checkClosed(m, 1, 2);
      CHECK(radialError(m, Eigen::Vector3d::Zero(), 0.5) < 0.01);
    }
    // A field that is exactly iso on whole planes of nodes (a cube with faces on grid planes).
    const Field box = [](const Eigen::Vector3d& x) { return 0.5 - x.cwiseAbs().maxCoeff(); };
    const Mesh m = polygonize(samplerOf(box), g, {0.0}, fullMode()).meshes.front();
    checkClosed(m, 1, 2);
    // The faces sit on node planes, each vertex moved off its node by at most 64 single-precision
    // ulps of the largest coordinate (1) so that no triangle collapses to zero area.
    const double margin = 64.0 * static_cast<double>(std::numeric_limits<float>::epsilon());
    double offPlane = 0.0;
    for (Eigen::Index v = 0; v < m.vertices.rows(); ++v) {
      offPlane = std::max(offPlane, std::abs(m.vertices.row(v).cwiseAbs().maxCoeff() - 0.5));
    }
    CHECK(offPlane <= margin * 1.0000001);
    CHECK(std::abs(volume(m) - 1.0) <= 6.0 * margin);
  }

  TEST_CASE("polygonize: a torus has χ = 0, two spheres give two components") {
    const GridSpec g = cube(1.0, 64);
    for (bool adaptive : {true, false}) {
      PolygonizeOptions o;
      o.adaptive = adaptive;
      const Mesh t = polygonize(samplerOf(torus(0.55, 0.22)), g, {0.0}, o).meshes.front();
      checkClosed(t, 1, 0);
      const double exact = 4.0 * kPi * kPi * 0.55 * 0.22;
      CHECK(std::abs(area(t) - exact) / exact < 0.03);
      const Field two = unite(sphere(Eigen::Vector3d(-0.45, 0.0, 0.1), 0.35),
                              sphere(Eigen::Vector3d(0.5, 0.1, -0.1), 0.3));
      const Mesh s = polygonize(samplerOf(two), g, {0.0}, o).meshes.front();
      checkClosed(s, 2, 4);
    }
  }

  TEST_CASE("polygonize: several iso values in one pass match separate passes") {
    const GridSpec g = cube(1.0, 48);
    const double h = g.cellSize()(0);
    const Eigen::Vector3d c(0.01, 0.02, -0.03);
    const FieldSampler f = samplerOf(sphere(c, 0.6));
    const std::vector<double> isos = {0.0, 0.2, -0.25, 0.0};
    int calls = 0;
    const FieldSampler counted = [&](const Points& q, Eigen::VectorXd& v) {
      ++calls;
      f(q, v);
    };
    for (bool adaptive : {true, false}) {
      PolygonizeOptions o;
      o.adaptive = adaptive;
      calls = 0;
      const PolygonizeResult all = polygonize(counted, g, isos, o);
      CHECK(calls == all.stats.samplerCalls);
      REQUIRE(all.meshes.size() == isos.size());
      for (std::size_t q = 0; q < isos.size(); ++q) {
        CAPTURE(q);
        const double r = 0.6 - isos[q];
        checkClosed(all.meshes[q], 1, 2);
        CHECK(radialError(all.meshes[q], c, r) < h * h / r);
        CHECK(std::abs(area(all.meshes[q]) - 4 * kPi * r * r) / (4 * kPi * r * r) < 0.03);
        const Mesh single = polygonize(f, g, {isos[q]}, o).meshes.front();
        CHECK(identical(all.meshes[q], single));
      }
      CHECK(identical(all.meshes[0], all.meshes[3]));
    }
  }

  TEST_CASE("polygonize: adaptive sampling gives the full mode's meshes, a thin sheet included") {
    struct Case {
      const char* name;
      Field field;
      GridSpec grid;
      std::vector<double> isos;
      std::int64_t components;
      std::int64_t euler;
    };
    const GridSpec g = cube(1.0, 64);
    const double h = g.cellSize()(0);
    GridSpec odd;  // non-cubic cells, counts that are not multiples of the coarse step
    odd.box =
        Eigen::AlignedBox3d(Eigen::Vector3d(-1.0, -0.9, -0.8), Eigen::Vector3d(1.1, 0.9, 0.85));
    odd.cells = Eigen::Vector3i(37, 50, 23);
    const Field ball = sphere(Eigen::Vector3d(0.05, 0.0, 0.0), 0.5);
    // The "spurious sheet": a disc 1.5 cells thick far from the sphere, barely above the iso value.
    const Field sheet = unite(ball, pancake(0.8, 0.4, 0.75 * h));
    const std::vector<Case> cases = {
        {"sphere", ball, g, {0.0, 0.1}, 1, 2},
        {"torus", torus(0.5, 0.2), g, {0.0, -0.05}, 1, 0},
        {"two spheres",
         unite(sphere(Eigen::Vector3d(-0.5, 0, 0), 0.3),
               sphere(Eigen::Vector3d(0.45, 0.05, 0), 0.35)),
         g,
         {0.0},
         2,
         4},
        {"thin sheet", sheet, g, {0.0}, 2, 4},
        {"odd grid", ball, odd, {0.0, 0.2}, 1, 2},
    };
    for (const Case& cs : cases) {
      CAPTURE(cs.name);
      const PolygonizeResult full = polygonize(samplerOf(cs.field), cs.grid, cs.isos, fullMode());
      for (int step : {8, 2, 64}) {
        CAPTURE(step);
        PolygonizeOptions o;
        o.coarseStep = step;
        const PolygonizeResult adaptive = polygonize(samplerOf(cs.field), cs.grid, cs.isos, o);
        CHECK(adaptive.stats.evaluatedNodes < full.stats.evaluatedNodes);
        for (std::size_t q = 0; q < cs.isos.size(); ++q) {
          CAPTURE(q);
          CHECK(identical(adaptive.meshes[q], full.meshes[q]));
          CHECK(topology(adaptive.meshes[q]).components == cs.components);
        }
      }
      for (const Mesh& m : full.meshes) checkClosed(m, cs.components, cs.euler);
    }
  }

  TEST_CASE("polygonize: a repeated extraction reuses only the chunks whose layers and neighbours kept their cells") {
    // A steep vertical disk (in the y-z plane) across several chunks of cell layers: the continued cells lie
    // in many layers, and a chunk next to them reports open cells in its neighbour's layer. One round of
    // continued cells closes the meshes, so two extractions; a reused chunk whose neighbour layer gained
    // cells would report stale open cells (already marked), which costs a third, full extraction. The disk
    // above the middle and its mirror image below: forgetting the layer above a chunk fails the first,
    // forgetting the one below the second (both checked by mutation).
    const GridSpec g = cube(1.0, 64);
    const double h = g.cellSize()(0);
    for (const double zc : {0.3, -0.3}) {
      CAPTURE(zc);
      const Field plate = [h, zc](const Eigen::Vector3d& x) {
        return -std::max(std::abs(x(0) - 0.3) - 0.75 * h, std::hypot(x(1), x(2) - zc) - 0.3);
      };
      const Field steep = [plate](const Eigen::Vector3d& x) {
        return 20.0 * unite(sphere(Eigen::Vector3d(0.02, -0.01, 0.0), 0.5), plate)(x);
      };
      const PolygonizeResult full = polygonize(samplerOf(steep), g, {0.0, 0.01}, fullMode());
      const PolygonizeResult adaptive = polygonize(samplerOf(steep), g, {0.0, 0.01});
      CHECK(adaptive.stats.continuedCells > 0);
      CHECK(adaptive.stats.reusedChunks > 0);
      CHECK(adaptive.stats.extractionRounds == 2);
      CHECK(full.stats.extractionRounds == 1);
      for (std::size_t q = 0; q < 2; ++q) {
        CAPTURE(q);
        CHECK(identical(adaptive.meshes[q], full.meshes[q]));
      }
    }
  }

  TEST_CASE("polygonize: surfaces crossing skipped blocks of a too steep field are followed") {
    // |∇f| = 20 breaks the default Lipschitz bound 2: coarse blocks around the thin brim are
    // skipped, the extraction finds the surface leaving the refined cells, and the continuation
    // samples cell by cell until the mesh is closed, reproducing the full mode's mesh.
    const GridSpec g = cube(1.0, 64);
    const double h = g.cellSize()(0);
    const Field brim =
        unite(sphere(Eigen::Vector3d(0.02, -0.01, 0.0), 0.5), pancake(0.3, 0.85, 0.75 * h));
    const Field steep = [brim](const Eigen::Vector3d& x) { return 20.0 * brim(x); };
    const PolygonizeResult full = polygonize(samplerOf(steep), g, {0.0, 0.01}, fullMode());
    const PolygonizeResult adaptive = polygonize(samplerOf(steep), g, {0.0, 0.01});
    CHECK(adaptive.stats.continuedCells > 0);
    CHECK(adaptive.stats.reusedChunks > 0);  // the chunks away from the continued cells are not contoured again
    CHECK(full.stats.extractionRounds == 1);
    CHECK(adaptive.stats.evaluatedNodes < full.stats.evaluatedNodes);
    for (std::size_t q = 0; q < 2; ++q) {
      CAPTURE(q);
      checkClosed(full.meshes[q], 1, 2);
      CHECK(identical(adaptive.meshes[q], full.meshes[q]));
    }
    // The same with the brim's thin cells refined: the repeated extraction reuses the first round's
    // tolerance tests and region (RefineCache) and still gives the full mode's meshes.
    PolygonizeOptions refinedFull = fullMode(), refinedAdaptive;
    refinedFull.refineLevels = refinedAdaptive.refineLevels = 2;
    refinedFull.refineTolerance = refinedAdaptive.refineTolerance = 0.05 * h;
    const PolygonizeResult rf = polygonize(samplerOf(steep), g, {0.0, 0.01}, refinedFull);
    const PolygonizeResult ra = polygonize(samplerOf(steep), g, {0.0, 0.01}, refinedAdaptive);
    CHECK(ra.stats.continuedCells > 0);
    CHECK(ra.stats.refinedCells > 0);
    CHECK(ra.stats.refinedCells == rf.stats.refinedCells);
    for (std::size_t q = 0; q < 2; ++q) {
      CAPTURE(q);
      checkClosed(rf.meshes[q], 1, 2);
      CHECK(identical(ra.meshes[q], rf.meshes[q]));
    }
    // Within the bound, nothing needs to be continued.
    const PolygonizeResult gentle = polygonize(samplerOf(brim), g, {0.0});
    CHECK(gentle.stats.continuedCells == 0);
    CHECK(identical(gentle.meshes[0], polygonize(samplerOf(brim), g, {0.0}, fullMode()).meshes[0]));
    // A steep sheet that touches nothing refined can be missed entirely, but the output stays
    // closed.
    const Field apart = [&](const Eigen::Vector3d& x) {
      return 20.0 *
             std::max(sphere(Eigen::Vector3d::Zero(), 0.3)(x), pancake(0.7, 0.5, 0.75 * h)(x));
    };
    const Mesh m = polygonize(samplerOf(apart), g, {0.0}).meshes[0];
    const Topology t = topology(m);
    CHECK(t.closedManifold());
    CHECK(t.components >= 1);
  }

  TEST_CASE("polygonize: random fields give closed oriented manifolds (exact hits included)") {
    GridSpec g;
    g.box = Eigen::AlignedBox3d(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1.0, 1.3, 0.9));
    g.cells = Eigen::Vector3i(21, 26, 17);
    for (std::uint32_t seed : {1u, 2u, 3u}) {
      CAPTURE(seed);
      const FieldSampler f = samplerOf(randomField(g, seed));
      const std::vector<double> isos = {0.0, 0.3, -0.5};
      const PolygonizeResult full = polygonize(f, g, isos, fullMode());
      PolygonizeOptions never;  // adaptive, but nothing can be skipped
      never.lipschitz = 1e9;
      never.coarseStep = 4;
      const PolygonizeResult all = polygonize(f, g, isos, never);
      CHECK(all.stats.evaluatedNodes == g.nodeCount());
      for (std::size_t q = 0; q < isos.size(); ++q) {
        CAPTURE(q);
        const Topology t = topology(full.meshes[q]);
        CHECK(t.faces > 100);
        CHECK(t.closedManifold());
        CHECK(t.euler % 2 == 0);
        CHECK(volume(full.meshes[q]) > 0.0);
        CHECK(identical(full.meshes[q], all.meshes[q]));
      }
    }
  }

  TEST_CASE("polygonize: duplexfit::analyzeTopology agrees with the test's own checks") {
    const GridSpec g = cube(1.0, 32), small = cube(1.0, 12);
    const std::vector<Field> fields = {
        sphere(Eigen::Vector3d(0.1, 0.0, -0.05), 0.6), torus(0.5, 0.2),
        unite(sphere(Eigen::Vector3d(-0.5, 0, 0), 0.3), sphere(Eigen::Vector3d(0.5, 0, 0), 0.3)),
        randomField(small, 7)};
    for (std::size_t i = 0; i < fields.size(); ++i) {
      CAPTURE(i);
      const Mesh m =
          polygonize(samplerOf(fields[i]), i + 1 < fields.size() ? g : small, {0.0}, fullMode())
              .meshes.front();
      const Topology mine = topology(m);
      const duplexfit::MeshTopology lib = duplexfit::analyzeTopology(m);
      CHECK(lib.watertight());
      CHECK(lib.manifold());
      CHECK(lib.oriented());
      CHECK(lib.degenerateFaces == 0);
      CHECK(static_cast<std::int64_t>(lib.components) == mine.components);
      CHECK(lib.eulerCharacteristic == mine.euler);
      CHECK(static_cast<std::int64_t>(lib.edges) == mine.edges);
      CHECK(duplexfit::surfaceArea(m) == doctest::Approx(area(m)).epsilon(1e-12));
      CHECK(duplexfit::signedVolume(m) == doctest::Approx(volume(m)).epsilon(1e-9));
    }
  }

  TEST_CASE("polygonize: tiny and flat grids work in both modes") {
    const Field ball = sphere(Eigen::Vector3d(0.1, -0.1, 0.05), 0.8);
    for (const Eigen::Vector3i& cells : {Eigen::Vector3i(1, 1, 1), Eigen::Vector3i(1, 2, 3),
                                         Eigen::Vector3i(17, 1, 9), Eigen::Vector3i(3, 40, 2)}) {
      CAPTURE(cells.transpose());
      GridSpec g = cube(1.0, 1);
      g.cells = cells;
      const PolygonizeResult full = polygonize(samplerOf(ball), g, {0.0, 0.5}, fullMode());
      CHECK(full.stats.evaluatedNodes == g.nodeCount());
      for (int step : {2, 8}) {
        PolygonizeOptions o;
        o.coarseStep = step;
        const PolygonizeResult adaptive = polygonize(samplerOf(ball), g, {0.0, 0.5}, o);
        for (std::size_t q = 0; q < 2; ++q) CHECK(identical(adaptive.meshes[q], full.meshes[q]));
      }
      for (const Mesh& m : full.meshes) {
        const Topology t = topology(m);
        CHECK(t.nonManifoldEdges == 0);
        CHECK(t.inconsistentEdges == 0);
        CHECK(t.nonManifoldVertices == 0);
      }
    }
  }

  TEST_CASE("polygonize: a surface cut by the grid boundary is open only on the boundary") {
    const GridSpec g = cube(0.5, 20);
    const Mesh m =
        polygonize(samplerOf(sphere(Eigen::Vector3d::Zero(), 0.6)), g, {0.0}).meshes.front();
    const Topology t = topology(m);
    CHECK(t.boundaryEdges > 0);
    CHECK(t.nonManifoldEdges == 0);
    CHECK(t.inconsistentEdges == 0);
    CHECK(t.nonManifoldVertices == 0);
    CHECK(t.components == 1);  // a sphere with 6 holes, one per box face
    CHECK(t.euler == 2 - 6);
    for (Eigen::Index f = 0; f < m.faces.rows(); ++f) {
      for (int c = 0; c < 3; ++c) {
        const Eigen::Vector3d v = m.vertices.row(m.faces(f, c)).transpose();
        CHECK(g.box.contains(v));
      }
    }
  }

  TEST_CASE("polygonize: output is independent of threads and batch size; progress and cancel") {
    const GridSpec g = cube(1.0, 48);
    const FieldSampler f = samplerOf(torus(0.5, 0.25));
    PolygonizeOptions o;
    o.threads = 1;
    const PolygonizeResult one = polygonize(f, g, {0.0, 0.1}, o);
    o.threads = 3;
    o.batchSize = 1000;
    duplexfit::testing::RecordingInterrupter recorder;
    const PolygonizeResult many = polygonize(f, g, {0.0, 0.1}, o, &recorder);
    CHECK(many.stats.samplerCalls > one.stats.samplerCalls);
    for (int q = 0; q < 2; ++q) CHECK(identical(one.meshes[q], many.meshes[q]));
    const std::vector<int>& percents = recorder.percents;
    REQUIRE(!percents.empty());
    CHECK(percents.back() == 100);
    for (std::size_t i = 1; i < percents.size(); ++i) CHECK(percents[i] >= percents[i - 1]);
    duplexfit::testing::RecordingInterrupter canceller;
    canceller.stopWhen = [](const duplexfit::testing::RecordingInterrupter& i) { return i.percents.size() >= 3; };
    CHECK_THROWS_AS(polygonize(f, g, {0.0}, o, &canceller), Cancelled);
    CHECK(canceller.percents.size() == 3);
  }

  TEST_CASE("polygonize: adaptive sampling of a sphere at 256³ evaluates under 10% of the nodes") {
    const GridSpec g = cube(1.0, 256);
    const Eigen::Vector3d c(0.003, -0.002, 0.001);
    const PolygonizeResult res = polygonize(samplerOf(sphere(c, 0.8)), g, {0.0});
    const double h = g.cellSize()(0);
    MESSAGE("256³ sphere: " << res.stats.evaluatedNodes << " of " << res.stats.totalNodes
                            << " nodes (" << 100.0 * res.stats.evaluatedFraction() << "%), "
                            << res.stats.refinedBlocks << "/" << res.stats.coarseBlocks
                            << " coarse blocks refined, sampling " << res.stats.samplingSeconds
                            << " s (sampler " << res.stats.samplerSeconds << " s), extraction "
                            << res.stats.extractionSeconds << " s, total " << res.stats.totalSeconds
                            << " s, " << res.meshes[0].faces.rows() << " triangles");
    CHECK(res.stats.evaluatedFraction() < 0.10);
    if (!kSlowBuild) checkClosed(res.meshes[0], 1, 2);  // closedness is covered on smaller grids
    CHECK(radialError(res.meshes[0], c, 0.8) < h * h / 0.8);
    CHECK(std::abs(area(res.meshes[0]) - 4 * kPi * 0.64) / (4 * kPi * 0.64) < 0.0005);
  }

  TEST_CASE("polygonize: a 512³ sphere (timing printed)" * doctest::skip(kSlowBuild)) {
    const GridSpec g = cube(1.0, 512);
    const Eigen::Vector3d c(0.003, -0.002, 0.001);
    const auto start = std::chrono::steady_clock::now();
    const PolygonizeResult res = polygonize(samplerOf(sphere(c, 0.8)), g, {0.0, 0.05});
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    MESSAGE("512³ sphere, 2 iso values: "
            << res.stats.evaluatedNodes << " of " << res.stats.totalNodes << " nodes ("
            << 100.0 * res.stats.evaluatedFraction() << "%), " << res.stats.samplerCalls
            << " sampler calls, sampling " << res.stats.samplingSeconds << " s (sampler "
            << res.stats.samplerSeconds << " s), extraction " << res.stats.extractionSeconds
            << " s, wall " << wall << " s, node storage " << res.stats.storageBytes / 1048576.0
            << " MiB, " << res.meshes[0].faces.rows() << " + " << res.meshes[1].faces.rows()
            << " triangles");
    const Topology t = topology(res.meshes[0]);
    CHECK(t.closedManifold());
    CHECK(t.components == 1);
    CHECK(t.euler == 2);
  }
}

TEST_SUITE("polygonize") {
  // The last refinement level tests each cell against its 2-block's sampled corners before
  // sampling it (a cell covered by those corners' Lipschitz balls cannot be crossed). The earlier
  // scheme, which sampled every node of each 2-block not skipped, evaluated 12.62% (256³) and
  // 7.64% (512³) here; the per-cell test gives 11.50% and 6.52%.
  TEST_CASE("polygonize: per-cell refinement lowers the evaluated fraction (two iso values)") {
    const Eigen::Vector3d c(0.003, -0.002, 0.001);
    for (int n : {256, 512}) {
      if (n == 512 && kSlowBuild) continue;
      const GridSpec g = cube(1.0, n);
      const PolygonizeResult res = polygonize(samplerOf(sphere(c, 0.8)), g, {0.0, 0.05});
      const PolygonizeResult full = n == 256 ? polygonize(samplerOf(sphere(c, 0.8)), g,
                                                          {0.0, 0.05}, fullMode())
                                             : PolygonizeResult{};
      MESSAGE(n << "³ sphere, iso 0 and 0.05: " << res.stats.evaluatedNodes << " of "
                << res.stats.totalNodes << " nodes (" << 100.0 * res.stats.evaluatedFraction()
                << "%), " << res.stats.samplerCalls << " sampler calls");
      CHECK(res.stats.continuedCells == 0);
      CHECK(res.stats.evaluatedFraction() < (n == 256 ? 0.120 : 0.070));
      for (std::size_t q = 0; q < full.meshes.size(); ++q) {
        CHECK(identical(res.meshes[q], full.meshes[q]));
      }
    }
  }

  TEST_CASE("polygonize: evaluated fraction on a 486×524×294 grid (printed)" *
            doctest::skip(kSlowBuild)) {
    GridSpec g;
    g.cells = Eigen::Vector3i(486, 524, 294);
    g.box = Eigen::AlignedBox3d(Eigen::Vector3d(-0.486, -0.524, -0.294),
                                Eigen::Vector3d(0.486, 0.524, 0.294));
    // h = 0.002: iso values 12 cells apart as in the CAD run. The earlier scheme evaluated 5.82%.
    const double h = g.cellSize()(0);
    const PolygonizeResult res =
        polygonize(samplerOf(sphere(Eigen::Vector3d(0.001, -0.002, 0.003), 0.27)), g,
                   {0.0, 12 * h});
    MESSAGE("486×524×294 sphere, iso 0 and 12h: " << res.stats.evaluatedNodes << " of "
            << res.stats.totalNodes << " nodes (" << 100.0 * res.stats.evaluatedFraction()
            << "%), " << res.stats.samplerCalls << " sampler calls, sampler cost at 1.4 µs/node "
            << 1.4e-6 * static_cast<double>(res.stats.evaluatedNodes) << " s");
    CHECK(res.stats.continuedCells == 0);
    CHECK(topology(res.meshes[0]).closedManifold());
  }

  TEST_CASE("estimatePolygonize is within a small factor of the node store and triangles of a sphere; the budget refuses before sampling") {
    // A sphere filling 80% of the box, as the fit's grids (5% and three cells of margin), and its inward offset.
    GridSpec grid;
    grid.box = Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.5), Eigen::Vector3d::Constant(0.5));
    grid.cells = Eigen::Vector3i::Constant(160);
    const std::vector<double> isos{0.0, 0.05};
    const PolygonizeOptions options;
    const duplexfit::PolygonizeEstimate e = duplexfit::estimatePolygonize(grid, isos.size(), options);
    const PolygonizeResult r = polygonize(samplerOf(sphere(Eigen::Vector3d::Zero(), 0.4)), grid, isos, options);
    double triangles = 0.0;
    for (const Mesh& m : r.meshes) triangles += static_cast<double>(m.faces.rows());
    const double storeRatio = e.storeBytes / static_cast<double>(r.stats.storageBytes);
    const double triangleRatio = e.triangles / triangles;
    MESSAGE("node store: estimate " << e.storeBytes << " bytes, actual " << r.stats.storageBytes << " (x" << storeRatio
                                    << "); triangles: estimate " << e.triangles << ", actual " << triangles << " (x"
                                    << triangleRatio << ")");
    // An estimate, not a bound: over the sphere's actual use, and by less than a factor of 4.
    CHECK(storeRatio >= 1.0);
    CHECK(storeRatio <= 4.0);
    CHECK(triangleRatio >= 1.0);
    CHECK(triangleRatio <= 4.0);
    // Full sampling stores every node.
    PolygonizeOptions full;
    full.adaptive = false;
    CHECK(duplexfit::estimatePolygonize(grid, 1, full).storedNodes >= static_cast<double>(grid.nodeCount()));

    // Over the budget: refused before the sampler is called once.
    PolygonizeOptions small;
    small.limits.maxMemoryBytes = std::uint64_t{1} << 20;
    int calls = 0;
    const FieldSampler counting = [&calls](const Points& q, Eigen::VectorXd& values) {
      ++calls;
      values = Eigen::VectorXd::Zero(q.rows());
    };
    try {
      polygonize(counting, grid, isos, small);
      FAIL("not refused");
    } catch (const duplexfit::MemoryLimitExceeded& ex) {
      const std::string what = ex.what();
      CHECK(what.find("polygonize: the 160x160x160 grid") != std::string::npos);
      CHECK(what.find("--max-memory 1 MiB") != std::string::npos);
      CHECK(what.find("--cell") != std::string::npos);
    }
    CHECK(calls == 0);
  }
}
