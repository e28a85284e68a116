// The robust field (sign anchors in empty space, medial constraints in thin parts) against exact truth:
// the thin torus (a ring around a large empty hole) gets no phantom solid in its hole and its offsets sit
// on the exact offset tori; a solid with a handle gets no blob inside the loop; a dumbbell whose neck is
// thinner than 2δ has an inward offset of exactly two pieces, and f on the neck's axis is the neck radius.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "data.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/preprocess.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/surfaces.hpp"
#include "duplexfit/winding.hpp"
#include "fit/anchors.hpp"
#include "spatial/disk_distance.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

const Device& robustDevice() { return testing::openclOrReferenceDevice(); }

// A solid given as a union of simple pieces, sampled area-uniformly on its boundary: each piece offers
// candidates on its own surface, kept when outside every other piece.
struct Piece {
  enum Kind { Sphere, TorusY, CylinderX } kind;
  Eigen::Vector3d c;
  double a, b;  // sphere: radius a; torus (axis y): R = a, r = b; cylinder (axis x): radius a, half length b
  double sdf(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d q = p - c;
    switch (kind) {
      case Sphere: return q.norm() - a;
      case TorusY: return std::hypot(std::hypot(q.x(), q.z()) - a, q.y()) - b;
      case CylinderX: {
        const double radial = std::hypot(q.y(), q.z()) - a, axial = std::abs(q.x()) - b;
        return std::min(std::max(radial, axial), 0.0) + std::hypot(std::max(radial, 0.0), std::max(axial, 0.0));
      }
    }
    return 0.0;
  }
  double area() const {
    switch (kind) {
      case Sphere: return 4 * M_PI * a * a;
      case TorusY: return 4 * M_PI * M_PI * a * b;
      case CylinderX: return 2 * M_PI * a * 2 * b;  // lateral surface only (the caps lie inside the spheres)
    }
    return 0.0;
  }
  // A uniform random point on the piece's surface and its outward normal.
  void sample(std::mt19937& rng, Eigen::Vector3d& p, Eigen::Vector3d& n) const {
    std::uniform_real_distribution<double> U(0.0, 1.0);
    switch (kind) {
      case Sphere: {
        const double z = 2 * U(rng) - 1, t = 2 * M_PI * U(rng), s = std::sqrt(1 - z * z);
        n = Eigen::Vector3d(s * std::cos(t), s * std::sin(t), z);
        p = c + a * n;
        return;
      }
      case TorusY: {
        double u, v;
        do {  // rejection for area uniformity: density ∝ R + r cos v
          u = 2 * M_PI * U(rng);
          v = 2 * M_PI * U(rng);
        } while (U(rng) * (a + b) > a + b * std::cos(v));
        const Eigen::Vector3d radial(std::cos(u), 0.0, std::sin(u));
        n = std::cos(v) * radial + std::sin(v) * Eigen::Vector3d::UnitY();
        p = c + a * radial + b * n;
        return;
      }
      case CylinderX: {
        const double t = 2 * M_PI * U(rng), x = (2 * U(rng) - 1) * b;
        n = Eigen::Vector3d(0.0, std::cos(t), std::sin(t));
        p = c + Eigen::Vector3d(x, 0.0, 0.0) + a * n;
        return;
      }
    }
  }
};

PointSet sampleUnion(const std::vector<Piece>& pieces, int n, unsigned seed) {
  std::mt19937 rng(seed);
  double total = 0.0;
  for (const Piece& p : pieces) total += p.area();
  std::vector<Eigen::Vector3d> pos, nrm;
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    const int want = static_cast<int>(std::lround(n * pieces[k].area() / total));
    for (int i = 0; i < want; ++i) {
      Eigen::Vector3d p, nn;
      pieces[k].sample(rng, p, nn);
      bool outside = true;
      for (std::size_t m = 0; m < pieces.size(); ++m) {
        if (m != k && pieces[m].sdf(p) < 0.0) outside = false;
      }
      if (!outside) continue;
      pos.push_back(p);
      nrm.push_back(nn);
    }
  }
  Points P(static_cast<Eigen::Index>(pos.size()), 3), N(static_cast<Eigen::Index>(pos.size()), 3);
  for (std::size_t i = 0; i < pos.size(); ++i) {
    P.row(static_cast<Eigen::Index>(i)) = pos[i].transpose();
    N.row(static_cast<Eigen::Index>(i)) = nrm[i].transpose();
  }
  return PointSet(P, N);
}

struct Fitted {
  FitResult fit;
  SurfaceResult surfaces;
};

Fitted fitAndExtract(const PointSet& cloud, double delta, double smoothing = 0.0) {
  FitOptions options;
  options.offsets = {delta};
  options.smoothing = smoothing;
  Fitted out{fit(robustDevice(), cloud, options), {}};
  out.surfaces = extractSurfaces(robustDevice(), out.fit.field, {0.0, delta});
  return out;
}

std::size_t anchorCount(const FitReport& r) {
  std::size_t n = 0;
  for (const LevelReport& l : r.levelReports) n += l.anchorsInside + l.anchorsOutside;
  return n;
}

/// A sampled torus (R 0.4, r 0.1) with what levelAnchors takes: inward normals, the winding number, the
/// points' index and their box grown by 0.15.
struct TorusForAnchors {
  Points normals;
  Points points = testing::sampledTorus(3000, 0.4, 0.1, &normals);
  Points inward = -normals;
  WindingNumber winding{points, normals};
  NeighborIndex index{points};
  Eigen::AlignedBox3d box = [this] {
    Eigen::AlignedBox3d b;
    for (Eigen::Index i = 0; i < points.rows(); ++i) b.extend(points.row(i).transpose());
    b.extend(b.min() - Eigen::Vector3d::Constant(0.15));
    b.extend(b.max() + Eigen::Vector3d::Constant(0.15));
    return b;
  }();
  detail::Anchors anchors(const detail::AnchorOptions& o) const {
    return detail::levelAnchors(box, points, inward, winding.areas(), index, winding, points, o);
  }
};

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("robust field: thin_torus_20k (and its noisy twin, denoised) has no phantom solid in its hole") {
    DUPLEXFIT_SHARED_DATA_DIR(dir);
    const double R = 0.42, r = 0.07;
    // Hole points farther than 0.1 (≫ 2 sample spacings) from the ring: f must be negative there.
    Points hole(4 * 16 + 1, 3);
    hole.row(0) << 0.0, 0.0, 0.0;
    for (int i = 0; i < 4; ++i) {
      for (int j = 0; j < 16; ++j) {
        const double rho = 0.06 * (i + 1), t = 2 * M_PI * j / 16;
        hole.row(1 + i * 16 + j) << rho * std::cos(t), rho * std::sin(t), (i % 2 == 0 ? 0.0 : 0.03);
      }
    }
    for (const bool noisy : {false, true}) {
#ifdef DUPLEXFIT_SANITIZED
      if (noisy) {  // the sanitizer build runs the clean cloud only (each fit is ~10x slower there)
        DUPLEXFIT_SKIP_PART("the noisy twin thin_torus_20k_noise0.5pct, in the sanitizer build");
        continue;
      }
#endif
      PointSet cloud = readPointCloud(dir + "/clouds/thin_torus_20k" + (noisy ? "_noise0.5pct" : "") + ".ply");
      cloud.mergeDuplicates();
      if (noisy) cloud = bilateralFilter(robustDevice(), cloud, BilateralOptions{}).points;
      for (const double delta : {0.02, -0.02}) {
        CAPTURE(noisy);
        CAPTURE(delta);
        const Fitted f = fitAndExtract(cloud, delta, noisy ? 0.2 : 0.0);
        CHECK(anchorCount(f.fit.report) > 0);
        const Eigen::VectorXd inHole = f.fit.field.evaluate(robustDevice(), hole).values;
        MESSAGE("f at the hole's centre " << inHole[0] << ", max over the hole " << inHole.maxCoeff());
        CHECK(inHole[0] < -0.1);
        CHECK(inHole.maxCoeff() < 0.0);
        // The sign of f against the exact torus at random points of the meshing box farther than 0.02
        // (≈ 3 sample spacings) from the surface and from the offset surface.
        {
          std::mt19937 rng(3);
          std::uniform_real_distribution<double> U(-0.6, 0.6), Z(-0.2, 0.2);
          Points q(20000, 3);
          Eigen::VectorXd sdf(q.rows());
          for (Eigen::Index i = 0; i < q.rows();) {
            const Eigen::Vector3d p(U(rng), U(rng), Z(rng));
            const double d = std::hypot(std::hypot(p.x(), p.y()) - R, p.z()) - r;
            if (std::abs(d) < 0.02 || std::abs(d + delta) < 0.02) continue;
            q.row(i) = p.transpose();
            sdf[i++] = d;
          }
          const Eigen::VectorXd v = f.fit.field.evaluate(robustDevice(), q).values;
          Eigen::Index wrong = 0;
          for (Eigen::Index i = 0; i < q.rows(); ++i) wrong += (v[i] > 0.0) != (sdf[i] < 0.0) ? 1 : 0;
          MESSAGE("sign of f wrong at " << wrong << " of " << q.rows() << " random points away from the surface");
          CHECK(static_cast<double>(wrong) <= 0.001 * static_cast<double>(q.rows()));
        }
        const Eigen::VectorXd onOffset = f.fit.field.evaluate(robustDevice(), testing::torusGrid(R, r - delta, 96)).values;
        Eigen::VectorXd err = (onOffset.array() - delta).abs() / std::abs(delta);
        std::sort(err.data(), err.data() + err.size());
        const double p99 = err[static_cast<Eigen::Index>(0.99 * static_cast<double>(err.size() - 1))];
        const double maxErr = err[err.size() - 1];
        MESSAGE("|f - delta| on the exact offset torus: mean " << err.mean() * 100 << "%, p99 " << p99 * 100
                                                              << "%, max " << maxErr * 100 << "% of |delta|");
        if (!noisy) {
          // Target 1% of |δ| everywhere: met by the mean and p99; the max (measured 1.4% inward, 6.5%
          // outward; 1.35% and 6.1% without anchors and medial points) sits over a sampling hole of the
          // random cloud at (u, v) = (1.28, 4.61), where the finest supports do not reach across.
          CHECK(err.mean() <= 0.002);
          CHECK(p99 <= 0.01);
          CHECK(maxErr <= (delta > 0 ? 0.02 : 0.08));
        } else {
          // Noise of σ = 0.005 (25% of δ) leaves the denoised surface itself that far off in places.
          CHECK(maxErr <= 0.5);
        }
        for (int s = 0; s < 2; ++s) {
          const MeshTopology t = analyzeTopology(f.surfaces.meshes[static_cast<std::size_t>(s)]);
          CAPTURE(s);
          CHECK(t.components == 1);
          CHECK(t.eulerCharacteristic == 0);
          CHECK(t.watertight());
        }
      }
    }
  }

  TEST_CASE("disk-soup distance: from neighbour lists found once, the same as from the index; mismatched lists are an error") {
    Points normals;
    const Points points = testing::fibonacciSphere(2000, 0.5, &normals);
    const WindingNumber winding(points, normals);
    const NeighborIndex index(points);
    Points queries(3, 3);
    queries << 0.0, 0.0, 0.0, 0.7, 0.0, 0.0, 0.1, 0.52, -0.05;
    const Eigen::VectorXd direct = detail::diskSoupDistance(queries, points, normals, winding.areas(), index);
    // Twenty neighbours found, twelve used: the first twelve of the exact sorted search.
    const NeighborLists lists = index.knnSearch(queries, 20);
    const Eigen::VectorXd reused = detail::diskSoupDistance(queries, points, normals, winding.areas(), lists, 12);
    CHECK((direct - reused).cwiseAbs().maxCoeff() == 0.0);
    CHECK(direct[0] == doctest::Approx(0.5).epsilon(0.01));  // the centre: the radius
    CHECK(direct[1] == doctest::Approx(0.2).epsilon(0.02));
    CHECK_THROWS_AS(detail::diskSoupDistance(queries.topRows(2), points, normals, winding.areas(), lists, 12),
                    InvalidArgument);
  }

  TEST_CASE("sign anchors: the distance band holds every grid cell a brute-force nearest distance puts in it") {
    // levelAnchors queries only the rings of cells that can reach the band (by the ring's distance bounds);
    // the band it finds must be exactly the brute-force one, at the σ/2 spacing (the occupied cells skipped)
    // and at the doubled spacing (nothing skipped by the lower bound).
    const TorusForAnchors t;
    const Points& points = t.points;
    const Eigen::AlignedBox3d& box = t.box;
    const double sigma = 0.1;
    for (const double spacing : {sigma / 2.0, sigma}) {
      detail::AnchorOptions o;
      o.spacing = spacing;
      o.minDistance = 0.75 * sigma;
      o.maxDistance = 2.0 * sigma;
      const detail::Anchors an = t.anchors(o);
      // The same grid, every cell's nearest input point by brute force.
      Eigen::Array3i n;
      for (int a = 0; a < 3; ++a) n[a] = std::max(1, static_cast<int>(std::ceil(box.sizes()[a] / spacing)));
      const Eigen::Vector3d lo = box.center() - 0.5 * spacing * n.cast<double>().matrix();
      std::size_t band = 0;
      for (int k = 0; k < n[2]; ++k) {
        for (int j = 0; j < n[1]; ++j) {
          for (int i = 0; i < n[0]; ++i) {
            const Eigen::RowVector3d c = (lo + spacing * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5)).transpose();
            const double d = std::sqrt((points.rowwise() - c).rowwise().squaredNorm().minCoeff());
            band += d >= o.minDistance && d <= o.maxDistance ? 1 : 0;
          }
        }
      }
      CAPTURE(spacing);
      CHECK(band > 100);
      CHECK(an.candidates == band);
      CHECK(an.inside + an.outside + an.ambiguous + an.disagreeing + an.crowded + an.nearOffset == band);
      CHECK(an.inside > 0);
      CHECK(an.outside > 0);
    }
  }

  TEST_CASE("sign anchors: an outside upper end drops the outside anchors beyond it and leaves every other anchor as it was") {
    // The finest anchored level's outside band ends at the level's reach (docs/method.md, "Sign of empty
    // space"): the same torus and grid with and without that end.
    const TorusForAnchors t;
    const Points& points = t.points;
    const double sigma = 0.1;
    detail::AnchorOptions o;
    o.spacing = sigma / 2.0;
    o.minDistance = 0.75 * sigma;
    o.maxDistance = 2.0 * sigma;
    const detail::Anchors all = t.anchors(o);
    o.outsideMaxDistance = 1.5 * sigma;
    const detail::Anchors near = t.anchors(o);
    const auto nearest = [&points](const Eigen::RowVector3d& c) {
      return std::sqrt((points.rowwise() - c).rowwise().squaredNorm().minCoeff());
    };
    // The anchors of `near` are those of `all` without the far outside ones, in the same order and with the
    // same targets (inside: target > 0).
    std::size_t next = 0, beyond = 0;
    for (Eigen::Index r = 0; r < all.positions.rows(); ++r) {
      const bool far = all.targets[r] < 0.0 && nearest(all.positions.row(r)) > o.outsideMaxDistance;
      beyond += far ? 1 : 0;
      if (far) continue;
      REQUIRE(next < static_cast<std::size_t>(near.positions.rows()));
      const auto row = static_cast<Eigen::Index>(next++);
      CHECK(near.positions.row(row) == all.positions.row(r));
      CHECK(near.targets[row] == all.targets[r]);
    }
    CHECK(next == static_cast<std::size_t>(near.positions.rows()));
    CHECK(beyond > 50);  // the end drops something here
    CHECK(near.farOutside == beyond);
    CHECK(near.inside == all.inside);
    CHECK(near.outside + near.farOutside == all.outside);
    CHECK(near.inside > 0);
    CHECK(near.outside > 0);
  }

  TEST_CASE("robust field: a solid with a handle gets no blob inside the loop") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (the thin-torus case covers the same code there; Release runs it)");
#endif
    // A ball (centre (−0.2, 0, 0), radius 0.25) and a ring (centre (0.2, 0, 0), R 0.2, r 0.05, axis y)
    // that enters it: one solid of genus 1; the loop's hole around (0.2, 0, 0) is 0.15 from both.
    const std::vector<Piece> pieces{{Piece::Sphere, {-0.2, 0.0, 0.0}, 0.25, 0.0},
                                    {Piece::TorusY, {0.2, 0.0, 0.0}, 0.2, 0.05}};
    const PointSet cloud = sampleUnion(pieces, 16000, 7);
    const Fitted f = fitAndExtract(cloud, 0.02);
    Points loop(5, 3);
    loop << 0.2, 0.0, 0.0, 0.15, 0.0, 0.05, 0.25, 0.0, -0.05, 0.2, 0.0, 0.08, 0.2, 0.0, -0.08;
    const Eigen::VectorXd v = f.fit.field.evaluate(robustDevice(), loop).values;
    MESSAGE("f inside the loop: max " << v.maxCoeff());
    CHECK(v.maxCoeff() < 0.0);
    const MeshTopology zero = analyzeTopology(f.surfaces.meshes[0]);
    CHECK(zero.components == 1);
    CHECK(zero.eulerCharacteristic == 0);  // genus 1: the loop stays open
    const MeshTopology off = analyzeTopology(f.surfaces.meshes[1]);
    CHECK(off.components == 1);
    CHECK(off.eulerCharacteristic == 0);
  }

  TEST_CASE("robust field: a dumbbell whose neck is thinner than 2δ has exactly the truth's two offset pieces") {
#ifdef DUPLEXFIT_SANITIZED
    DUPLEXFIT_SKIP("in the sanitizer build (the thin-torus case covers the same code there; Release runs it)");
#endif
    // Balls of radius 0.2 at x = ±0.3 joined by a neck of radius 0.04; δ = 0.06 inward: the exact offset
    // is two balls of radius 0.14 (the neck, thinner than 2δ, has no δ set), and f on the neck's axis is
    // the neck's radius.
    const std::vector<Piece> pieces{{Piece::Sphere, {-0.3, 0.0, 0.0}, 0.2, 0.0},
                                    {Piece::Sphere, {0.3, 0.0, 0.0}, 0.2, 0.0},
                                    {Piece::CylinderX, {0.0, 0.0, 0.0}, 0.04, 0.12}};
    const PointSet cloud = sampleUnion(pieces, 20000, 11);
    const double delta = 0.06;
    const Fitted f = fitAndExtract(cloud, delta);
    std::size_t medial = 0;
    for (const LevelReport& l : f.fit.report.levelReports) medial += l.offsetMedial.empty() ? 0 : l.offsetMedial[0];
    CHECK(medial > 0);
    CHECK(analyzeTopology(f.surfaces.meshes[0]).components == 1);
    CHECK(analyzeTopology(f.surfaces.meshes[1]).components == 2);
    Points axis(5, 3);
    for (int i = 0; i < 5; ++i) axis.row(i) << -0.04 + 0.02 * i, 0.0, 0.0;
    const Eigen::VectorXd v = f.fit.field.evaluate(robustDevice(), axis).values;
    MESSAGE("f on the neck's axis: " << v.transpose() << " (true 0.04)");
    CHECK((v.array() - 0.04).abs().maxCoeff() <= 0.25 * 0.04);
    // The offset balls sit at radius 0.14 (away from the neck).
    Points ball(3, 3);
    ball << -0.44, 0.0, 0.0, -0.3, 0.14, 0.0, 0.3, 0.0, -0.14;
    const Eigen::VectorXd b = f.fit.field.evaluate(robustDevice(), ball).values;
    CHECK((b.array() - delta).abs().maxCoeff() <= 0.02 * delta);
  }
}
