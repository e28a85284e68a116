// The fast winding number of an oriented cloud against its direct sum and against the truth: ≈ 1 inside
// a sampled sphere and torus, ≈ 0 outside, tree approximation within 0.05 of the exact sum.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "duplexfit/error.hpp"
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
