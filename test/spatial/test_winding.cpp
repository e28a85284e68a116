// The fast winding number of an oriented cloud against its direct sum and against the truth: ≈ 1 inside
// a sampled sphere and torus, ≈ 0 outside, tree approximation within 0.05 of the exact sum.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "data.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/winding.hpp"
#include "shapes.hpp"

using namespace duplexfit;

TEST_SUITE("spatial") {
  TEST_CASE("winding number: sphere and torus, tree vs direct sum, inside/outside") {
    for (int shape = 0; shape < 2; ++shape) {
      CAPTURE(shape);
      Points normals;
      const Points points = shape == 0 ? testing::fibonacciSphere(6000, 0.5, &normals)
                                       : testing::sampledTorus(8000, 0.3, 0.15, &normals);
      const WindingNumber w(points, normals);
      // Areas add up to the surface's area (4π r², 4π² R r) within a few percent.
      const double area = w.areas().sum();
      const double truth = shape == 0 ? 4 * M_PI * 0.25 : 4 * M_PI * M_PI * 0.3 * 0.15;
      CHECK(area == doctest::Approx(truth).epsilon(0.08));
      std::mt19937 rng(5);
      std::uniform_real_distribution<double> U(-0.8, 0.8);
      Points q(400, 3);
      Eigen::VectorXd sdf(400);
      Eigen::Index m = 0;
      while (m < q.rows()) {
        const Eigen::Vector3d p(U(rng), U(rng), U(rng));
        const double d = shape == 0 ? p.norm() - 0.5 : std::hypot(std::hypot(p.x(), p.y()) - 0.3, p.z()) - 0.15;
        if (std::abs(d) < 0.05) continue;  // away from the samples (spacing ≈ 0.01)
        q.row(m) = p.transpose();
        sdf[m++] = d;
      }
      const Eigen::VectorXd fast = w.evaluate(q), exact = w.exact(q);
      // Second-order expansion at β = 3 (measured: sphere max 0.030, mean 0.0016), ample for a sign.
      const double err = (fast - exact).cwiseAbs().maxCoeff();
      MESSAGE("max |tree - direct| " << err << ", mean " << (fast - exact).cwiseAbs().mean());
      CHECK(err <= 0.05);
      CHECK((fast - exact).cwiseAbs().mean() <= 0.005);
      for (Eigen::Index i = 0; i < q.rows(); ++i) {
        CAPTURE(i);
        if (sdf[i] < 0) {
          CHECK(exact[i] == doctest::Approx(1.0).epsilon(0.05));
        } else {
          CHECK(std::abs(exact[i]) <= 0.05);
        }
      }
    }
  }

  TEST_CASE("winding number: the anchors' quick pass at beta 2 stays near beta 3 beyond three spacings") {
    // levelAnchors takes β = 2 first and asks β = 3 again only where the quick value is within 0.2 of a
    // threshold (lib/fit/anchors.cpp). Anchors lie at least three sample spacings (√ of the median point
    // area) from the cloud; there the two must differ by well under 0.2, or a decision could change. The
    // shared clouds with the largest differences measured (wheel_118k 0.059, thin_torus_20k 0.044) and
    // the analytic sphere and torus; queries pushed along the normals by 3 spacings to 8% of the side.
    std::vector<std::pair<std::string, std::pair<Points, Points>>> clouds;
    {
      Points n1, n2;
      Points p1 = testing::fibonacciSphere(6000, 0.5, &n1);
      Points p2 = testing::sampledTorus(8000, 0.3, 0.15, &n2);
      clouds.push_back({"sphere", {p1, n1}});
      clouds.push_back({"torus", {p2, n2}});
    }
    const std::string dir = testing::findSharedData();
    if (!dir.empty()) {
      for (const char* name : {"wheel_118k", "thin_torus_20k"}) {
        const PointSet c = readPointCloud(dir + "/clouds/" + name + ".ply");
        clouds.push_back({name, {c.positions(), c.normals()}});
      }
    } else {
      MESSAGE("shared data not found: the analytic clouds only");
    }
    for (const auto& [name, cloud] : clouds) {
      CAPTURE(name);
      const Points& p = cloud.first;
      const Points& n = cloud.second;
      const WindingNumber w(p, n);
      std::vector<double> areas(w.areas().data(), w.areas().data() + w.areas().size());
      std::nth_element(areas.begin(), areas.begin() + static_cast<std::ptrdiff_t>(areas.size() / 2), areas.end());
      const double spacing = std::sqrt(areas[areas.size() / 2]);
      const double side = (p.colwise().maxCoeff() - p.colwise().minCoeff()).maxCoeff();
      std::mt19937 rng(11);
      std::uniform_real_distribution<double> u(0.0, 1.0);
      Points q(p.rows(), 3);
      for (Eigen::Index i = 0; i < p.rows(); ++i) {
        q.row(i) = p.row(i) + (i % 2 == 0 ? 1.0 : -1.0) * (3.0 * spacing + 0.08 * side * u(rng)) * n.row(i);
      }
      const NeighborLists nearest = NeighborIndex(p).knnSearch(q, 1);
      const Eigen::VectorXd w3 = w.evaluate(q), w2 = w.evaluate(q, 2.0);
      CHECK(w.evaluate(q, 3.0) == w3);  // the default β is 3
      double worst = 0.0;
      Eigen::Index kept = 0;
      for (Eigen::Index i = 0; i < q.rows(); ++i) {
        if (nearest.distances[static_cast<std::size_t>(i)] < 3.0 * spacing) continue;
        ++kept;
        worst = std::max(worst, std::abs(w2[i] - w3[i]));
      }
      MESSAGE(name << ": " << kept << " queries, max |w(beta 2) - w(beta 3)| " << worst);
      CHECK(kept > q.rows() / 2);
      CHECK(worst <= 0.1);
    }
    CHECK_THROWS_AS(WindingNumber(Points::Zero(1, 3), Points::Zero(1, 3)).evaluate(Points::Zero(1, 3), 0.0),
                    InvalidArgument);
  }

  TEST_CASE("winding number: bad input") {
    Points p(2, 3), n(3, 3);
    p.setZero();
    n.setZero();
    CHECK_THROWS_AS(WindingNumber(p, n), InvalidArgument);
    CHECK_THROWS_AS(estimatePointAreas(p, n, 4), InvalidArgument);
    const Points empty(0, 3);
    // An index over other points is refused; one over the same points gives the same areas.
    Points q = Points::Random(50, 3), m = Points::Zero(50, 3);
    m.col(2).setOnes();
    CHECK_THROWS_AS(estimatePointAreas(q, m, 4, NeighborIndex(q.topRows(49))), InvalidArgument);
    CHECK(estimatePointAreas(q, m, 4, NeighborIndex(q)) == estimatePointAreas(q, m, 4));
    const WindingNumber none(empty, empty);
    CHECK(none.evaluate(Points::Zero(3, 3)).cwiseAbs().maxCoeff() == 0.0);
  }
}
