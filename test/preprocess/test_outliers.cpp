// findOutliers: far points beyond the bulk's box and isolated specks inside it (k-th neighbour distance
// against the cloud's median), and no false alarm on the shared clouds.
#include <doctest/doctest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "data.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/preprocess.hpp"
#include "shapes.hpp"

using namespace duplexfit;

TEST_SUITE("preprocess") {
  TEST_CASE("outliers: a far point and a speck in the hole are found, the sphere is not") {
    const Points sphere = testing::fibonacciSphere(40000, 0.5);  // spacing about 0.0044
    // A speck of 3 points at the centre (0.5 from every surface point: its 8th neighbour about 30x farther
    // than the sphere points') and one far point.
    Points p(sphere.rows() + 4, 3);
    p.topRows(sphere.rows()) = sphere;
    p.row(sphere.rows()) << 0.0, 0.0, 0.0;
    p.row(sphere.rows() + 1) << 0.001, 0.0, 0.0;
    p.row(sphere.rows() + 2) << 0.0, 0.001, 0.0;
    p.row(sphere.rows() + 3) << 1e4, 0.0, 0.0;
    const OutlierReport r = findOutliers(p);
    CHECK(r.outsideBox == 1);
    CHECK(r.worst == sphere.rows() + 3);
    CHECK(r.isolated == 3);
    REQUIRE(r.indices.size() == 4);
    for (int k = 0; k < 4; ++k) CHECK(r.indices[static_cast<std::size_t>(k)] == sphere.rows() + k);
    CHECK(r.worstIsolation > 20.0);
    CHECK(r.medianNeighbourDistance > 0.0);
    const std::string text = r.describe(p);
    CHECK(text.find("1 point far outside") != std::string::npos);
    CHECK(text.find("3 points isolated from the rest") != std::string::npos);
    // The sphere alone: nothing. With the isolation test off, only the far point.
    CHECK(findOutliers(sphere).indices.empty());
    OutlierOptions boxOnly;
    boxOnly.isolationFactor = 0.0;
    const OutlierReport b = findOutliers(p, boxOnly);
    CHECK(b.indices.size() == 1);
    CHECK(b.isolated == 0);
    CHECK(b.medianNeighbourDistance == 0.0);
    // Bad options are clear errors.
    OutlierOptions bad;
    bad.isolationFactor = 0.5;
    CHECK_THROWS_AS(findOutliers(p, bad), InvalidArgument);
    bad.isolationFactor = 20.0;
    bad.neighbours = 0;
    CHECK_THROWS_AS(findOutliers(p, bad), InvalidArgument);
  }

  TEST_CASE("outliers: none in the shared clouds (real scans with sparse regions included)") {
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    for (const char* name : {"maxplanck_12k", "igea_72k_right90", "bunny_35k_noise0.5pct", "fandisk_50k_noise0.5pct",
                             "wheel_118k", "thin_torus_20k_noise0.5pct"}) {
      CAPTURE(name);
      const PointSet cloud = readPointCloud(dir + "/clouds/" + name + ".ply");
      const OutlierReport r = findOutliers(cloud.positions());
      CHECK(r.indices.empty());
      CHECK(r.medianNeighbourDistance > 0.0);
    }
  }
}
