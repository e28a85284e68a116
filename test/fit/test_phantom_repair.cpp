// The phantom repair (repairPhantoms, docs/method.md "Phantom repair"): a blob of f > 0 planted in empty
// space beside a fitted sphere is a zero-level component without input points; the repair removes it from
// the field (f < 0 there, as the exact signed distance says) and names its faces, while f at the samples
// and the sphere's mesh stay where they were. In the fit suite (label device).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "duplexfit/field.hpp"
#include "duplexfit/fit.hpp"
#include "duplexfit/phantom_repair.hpp"
#include "duplexfit/self_check.hpp"
#include "duplexfit/surfaces.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

const Device& repairDevice() { return testing::openclOrReferenceDevice(); }

/// n points on the sphere of radius r about the origin (Fibonacci lattice) with outward normals.
PointSet sphere(int n, double r) {
  Points p(n, 3), nn(n, 3);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, s = std::sqrt(1.0 - z * z), t = golden * i;
    nn.row(i) << s * std::cos(t), s * std::sin(t), z;
    p.row(i) = r * nn.row(i);
  }
  return PointSet(p, nn);
}

/// The sphere of radius 0.3 sampled by 3,000 points, fitted with one inward offset of 0.03 (the fit is
/// shared by the cases, as their planted fields differ only in their added centres).
struct FittedSphere {
  double radius = 0.3, delta = 0.03;
  PointSet cloud;
  FitResult fitted;
  double sigma = 0.0;  ///< σ_M, input units
};

const FittedSphere& fittedSphere() {
  static const FittedSphere s = [] {
    FittedSphere f;
    f.cloud = sphere(3000, f.radius);
    FitOptions fo;
    fo.offsets = {f.delta};
    f.fitted = fit(repairDevice(), f.cloud, fo);
    f.sigma = f.fitted.field.levels().back().sigma / f.fitted.field.normalization().scale;
    return f;
  }();
  return s;
}

/// `clean` with centres of its finest level added at the given points (input units), each weighted so that f
/// there becomes the value given (the centres lie more than σ_M apart: each adds 1 × its weight at its own
/// point only).
ImplicitField plantCentres(const ImplicitField& clean, const std::vector<std::pair<Eigen::Vector3d, double>>& centres) {
  const Normalization& norm = clean.normalization();
  std::vector<FieldLevel> levels = clean.levels();
  FieldLevel& finest = levels.back();
  const Eigen::Index n = finest.centres.rows();
  finest.centres.conservativeResize(n + static_cast<Eigen::Index>(centres.size()), 3);
  finest.weights.conservativeResize(n + static_cast<Eigen::Index>(centres.size()));
  for (std::size_t k = 0; k < centres.size(); ++k) {
    const auto row = n + static_cast<Eigen::Index>(k);
    finest.centres.row(row) = norm.scale * (centres[k].first - norm.centre).transpose();
    finest.weights[row] = (centres[k].second - clean.value(centres[k].first)) * norm.scale;
  }
  return ImplicitField(norm, clean.f0(), levels, clean.offsets(), clean.bounds());
}

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("phantom repair: a blob planted beside a sphere leaves the field and the mesh; the sphere stays") {
    const FittedSphere& fs = fittedSphere();
    const double radius = fs.radius, delta = fs.delta, sigma = fs.sigma;
    const PointSet& cloud = fs.cloud;
    const ImplicitField& clean = fs.fitted.field;
    MESSAGE("sigma_M " << sigma);
    REQUIRE(sigma < 0.1);

    // The blob: one centre of the finest level 2σ_M outside the sphere, lifting f there to +σ_M (a ball of about σ_M/4).
    // Along the box diagonal, so that it lies inside the cloud's box (which the grid covers).
    const Eigen::Vector3d blob = (radius + 2.0 * sigma) * Eigen::Vector3d(1.0, 1.0, 1.0).normalized();
    CHECK(clean.value(blob) < 0.0);
    const ImplicitField planted = plantCentres(clean, {{blob, sigma}});
    REQUIRE(planted.value(blob) > 0.0);

    const std::vector<double> isos{0.0, delta};
    const SurfaceResult meshes = extractSurfaces(repairDevice(), planted, isos);
    std::size_t components = 0;
    const std::vector<Index> labels = faceComponents(meshes.meshes[0], &components);
    REQUIRE(components == 2);
    const std::vector<EmptyComponent> empty = emptyZeroLevelComponents(meshes.meshes[0], cloud.positions(), 1.0);
    REQUIRE(empty.size() == 1);
    CHECK(empty[0].box.contains(blob));

    const FieldEvaluator evaluator(repairDevice(), planted);
    const PhantomRepairResult r = repairPhantoms(repairDevice(), Precision::Float, planted, evaluator, cloud.positions(),
                                                 cloud.normals(), meshes.meshes, isos, empty);
    const PhantomRepairReport& rep = r.report;
    MESSAGE("repair: " << rep.anchors << " anchors, " << rep.keepPoints << " keep points, " << rep.rounds
                       << " round(s), moved " << rep.maxChange << ", deviation " << rep.maxDeviation << ", refused '"
                       << rep.refused << "'");
    CHECK(rep.candidates == 1);
    CHECK(rep.notPhantom == 0);
    REQUIRE(rep.repaired == 1);
    REQUIRE(r.field.has_value());
    CHECK(rep.refused.empty());
    // The faces named are exactly the blob's component.
    std::size_t blobFaces = 0;
    for (const Index l : labels) blobFaces += l == static_cast<Index>(empty[0].component) ? 1 : 0;
    REQUIRE(r.removedFaces.size() == 2);
    CHECK(r.removedFaces[0].size() == blobFaces);
    // The blob (f up to +σ_M) holds a component of the δ level too; it goes with it.
    std::size_t offsetComponents = 0;
    faceComponents(meshes.meshes[1], &offsetComponents);
    CHECK(offsetComponents == 2);
    CHECK(!r.removedFaces[1].empty());
    CHECK(rep.offsetFaces == r.removedFaces[1].size());
    CHECK(rep.repairedFaces == blobFaces);

    // Against the truth: f < 0 over the blob (the exact signed distance there is −2σ_M .. −σ_M), and within
    // a fifth of it at the blob's centre.
    const ImplicitField& fixed = *r.field;
    const double after = fixed.value(blob);
    MESSAGE("f at the blob: planted " << planted.value(blob) << ", repaired " << after << ", exact " << -2.0 * sigma);
    CHECK(after < 0.0);
    CHECK(std::abs(after + 2.0 * sigma) <= 0.2 * 2.0 * sigma);
    for (const double dz : {-0.5, -0.25, 0.25, 0.5}) {
      for (const double dx : {-0.5, 0.0, 0.5}) {
        CHECK(fixed.value(blob + sigma * Eigen::Vector3d(dx, dz, 0.0)) < 0.0);
      }
    }
    // f at the samples unchanged; the moved vertices stay within the bound and end on their level sets.
    const Eigen::VectorXd f0 = planted.evaluate(repairDevice(), cloud.positions()).values;
    const Eigen::VectorXd f1 = fixed.evaluate(repairDevice(), cloud.positions()).values;
    CHECK((f1 - f0).cwiseAbs().maxCoeff() <= 1e-5);
    CHECK(rep.maxChange <= 5e-3 * 0.6);
    CHECK(rep.maxDeviation <= 1e-4);
    // The moved vertices stay on the exact sphere (and its offset), as near as the extraction put them.
    double worst = 0.0;
    for (std::size_t j = 0; j < r.moves.size(); ++j) {
      for (const auto& [v, x] : r.moves[j]) {
        worst = std::max(worst, std::abs(x.norm() - (j == 0 ? radius : radius - delta)));
        (void)v;
      }
    }
    CHECK(worst <= 2e-3);

    // The fitted field without the blob: no candidate, nothing to repair.
    const SurfaceResult plain = extractSurfaces(repairDevice(), clean, isos);
    CHECK(emptyZeroLevelComponents(plain.meshes[0], cloud.positions(), 1.0).empty());
  }
  TEST_CASE("phantom repair: a phantom whose correction fails a check is left out, the other one repaired") {
    const FittedSphere& fs = fittedSphere();
    const double radius = fs.radius, delta = fs.delta, sigma = fs.sigma;
    const PointSet& cloud = fs.cloud;
    const ImplicitField& clean = fs.fitted.field;
    // Blob A 2σ_M outside the sphere, blob B σ_M outside on another diagonal: B's correction moves the
    // sphere's meshes more than A's, and away from the samples (a move beyond the bound that ends within
    // it of where the level set was or of its distance to the samples is accepted: at 1.4σ_M, B's
    // 3.4e-5 did, its vertices staying within 3e-5 of the samples' disks).
    const Eigen::Vector3d a = (radius + 2.0 * sigma) * Eigen::Vector3d(1.0, 1.0, 1.0).normalized();
    const Eigen::Vector3d b = (radius + 1.0 * sigma) * Eigen::Vector3d(-1.0, -1.0, 1.0).normalized();
    const ImplicitField planted = plantCentres(clean, {{a, sigma}, {b, 0.6 * sigma}});
    const std::vector<double> isos{0.0, delta};
    const SurfaceResult meshes = extractSurfaces(repairDevice(), planted, isos);
    const std::vector<EmptyComponent> empty = emptyZeroLevelComponents(meshes.meshes[0], cloud.positions(), 1.0);
    REQUIRE(empty.size() == 2);
    const FieldEvaluator evaluator(repairDevice(), planted);
    // With the default bound both go.
    PhantomRepairOptions near;
    near.boxMargin = 0.25;
    const PhantomRepairResult both = repairPhantoms(repairDevice(), Precision::Float, planted, evaluator,
                                                    cloud.positions(), cloud.normals(), meshes.meshes, isos, empty, near);
    MESSAGE("both: repaired " << both.report.repaired << ", left out " << both.report.refusedPhantoms << " ('" << both.report.firstRefusal << "'), moved " << both.report.maxChange << ", refused '"
                              << both.report.refused << "'");
    REQUIRE(both.report.repaired == 2);
    // A alone moves the meshes less than the pair (B's correction reaches the sphere): a bound between the
    // two (as a fraction of the side, 0.6) leaves B out.
    std::vector<EmptyComponent> onlyA;
    for (const EmptyComponent& e : empty) {
      if (e.box.contains(a)) onlyA.push_back(e);
    }
    REQUIRE(onlyA.size() == 1);
    const PhantomRepairResult alone = repairPhantoms(repairDevice(), Precision::Float, planted, evaluator,
                                                     cloud.positions(), cloud.normals(), meshes.meshes, isos, onlyA, near);
    REQUIRE(alone.report.repaired == 1);
    REQUIRE(alone.report.maxChange < 0.9 * both.report.maxChange);
    PhantomRepairOptions tight;
    tight.boxMargin = 0.25;  // the anchors over the blobs only (the default σ_M reaches the sphere from both)
    tight.maxChange = 0.5 * (alone.report.maxChange + both.report.maxChange) / 0.6;
    const PhantomRepairResult one = repairPhantoms(repairDevice(), Precision::Float, planted, evaluator,
                                                   cloud.positions(), cloud.normals(), meshes.meshes, isos, empty, tight);
    const PhantomRepairReport& rep = one.report;
    MESSAGE("tight: repaired " << rep.repaired << ", left out " << rep.refusedPhantoms << " ('" << rep.firstRefusal
                               << "'), moved " << rep.maxChange);
    CHECK(rep.repaired == 1);
    CHECK(rep.refusedPhantoms == 1);
    CHECK(rep.refused.empty());
    CHECK(rep.firstRefusal.find("moves another part") != std::string::npos);
    REQUIRE(one.field.has_value());
    CHECK(one.field->value(a) < 0.0);  // A repaired
    CHECK(one.field->value(b) > 0.0);  // B left as it was
    REQUIRE(one.removedFaces.size() == 2);
    CHECK(rep.maxChange <= tight.maxChange * 0.6);
  }
  TEST_CASE("phantom repair: a void planted inside a sphere under its offset: the offset is handed back to extract again") {
    const FittedSphere& fs = fittedSphere();
    const double radius = fs.radius, delta = fs.delta, sigma = fs.sigma;
    const PointSet& cloud = fs.cloud;
    const ImplicitField& clean = fs.fitted.field;
    // The void: one centre of the finest level δ + σ_M/2 deep, lowering f there to −σ_M/2. The δ level wraps
    // it and, so near the offset sheet, joins it: a lobe of the offset, not a component of its own, which
    // no vertex move can take back (its vertices find no level set once the void is filled).
    const Eigen::Vector3d hole = (radius - delta - 0.5 * sigma) * Eigen::Vector3d(1.0, -1.0, 1.0).normalized();
    CHECK(clean.value(hole) > 0.0);
    const ImplicitField planted = plantCentres(clean, {{hole, -0.5 * sigma}});
    REQUIRE(planted.value(hole) < 0.0);

    const std::vector<double> isos{0.0, delta};
    const SurfaceResult meshes = extractSurfaces(repairDevice(), planted, isos);
    std::size_t offsetComponents = 0;
    faceComponents(meshes.meshes[1], &offsetComponents);
    CHECK(offsetComponents == 1);  // the lobe is joined to the offset sheet
    const std::vector<EmptyComponent> empty = emptyZeroLevelComponents(meshes.meshes[0], cloud.positions(), 1.0);
    REQUIRE(empty.size() == 1);
    CHECK(empty[0].box.contains(hole));
    const FieldEvaluator evaluator(repairDevice(), planted);

    // Moves only (the library's default): refused, the offset's lobe cannot follow.
    const PhantomRepairResult moves = repairPhantoms(repairDevice(), Precision::Float, planted, evaluator,
                                                     cloud.positions(), cloud.normals(), meshes.meshes, isos, empty);
    MESSAGE("moves only: repaired " << moves.report.repaired << ", refused '" << moves.report.refused << "'");
    CHECK(moves.report.repaired == 0);
    CHECK(!moves.field.has_value());
    CHECK(moves.report.refused.find("surface 1") != std::string::npos);

    // Extraction again allowed: repaired; the offset mesh is handed back near the correction, not moved.
    PhantomRepairOptions again;
    again.reextractMeshes = true;
    const PhantomRepairResult r = repairPhantoms(repairDevice(), Precision::Float, planted, evaluator, cloud.positions(),
                                                 cloud.normals(), meshes.meshes, isos, empty, again);
    const PhantomRepairReport& rep = r.report;
    MESSAGE("again: repaired " << rep.repaired << ", handed back " << rep.reextracted << ", moved " << rep.maxChange
                               << ", refused '" << rep.refused << "'");
    REQUIRE(rep.repaired == 1);
    REQUIRE(r.field.has_value());
    CHECK(rep.reextracted == 1);
    REQUIRE(r.reextract.size() == 2);
    CHECK(!r.reextract[1].empty());
    CHECK(r.moves[1].empty());
    // Every point handed back lies near the void, within the correction's reach (anchors up to σ_M beyond
    // the void's box, keep points 2σ_M from them, vertices within σ_M of those).
    double reach = 0.0;
    for (const Eigen::Vector3d& x : r.reextract[1]) reach = std::max(reach, (x - hole).norm());
    CHECK(reach <= 5.5 * sigma);
    // Against the truth, the exact signed distance r − |x| (inside > 0): at the void δ + σ_M/2, within a
    // fifth; along the void's ray, f within 5% of δ of it from the surface down to the offset and above δ
    // from a tenth of σ_M below the offset to past the void (no lobe of the δ level left). The offset
    // companions beside the void, which the void had pulled down to half of δ, get δ back (without that, f
    // at depth δ stayed 0.015 of the exact 0.03 and the repaired offset kept a bump towards the surface).
    const ImplicitField& fixed = *r.field;
    MESSAGE("f at the void: planted " << planted.value(hole) << ", repaired " << fixed.value(hole) << ", exact "
                                      << delta + 0.5 * sigma << "; " << rep.restored << " keep points restored");
    CHECK(rep.restored > 0);
    CHECK(fixed.value(hole) > delta);
    CHECK(std::abs(fixed.value(hole) - (delta + 0.5 * sigma)) <= 0.2 * (delta + 0.5 * sigma));
    const Eigen::Vector3d ray = hole.normalized();
    for (int k = 1; k <= 10; ++k) {
      const double depth = 0.1 * k * delta;
      CAPTURE(depth);
      CHECK(std::abs(fixed.value((radius - depth) * ray) - depth) <= 0.05 * delta);
    }
    for (double depth = delta + 0.1 * sigma; depth <= delta + 1.5 * sigma; depth += 0.1 * sigma) {
      CAPTURE(depth);
      CHECK(fixed.value((radius - depth) * ray) > delta);
    }
    const Eigen::VectorXd f0 = planted.evaluate(repairDevice(), cloud.positions()).values;
    const Eigen::VectorXd f1 = fixed.evaluate(repairDevice(), cloud.positions()).values;
    CHECK((f1 - f0).cwiseAbs().maxCoeff() <= 1e-5);
  }
}
