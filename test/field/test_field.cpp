// ImplicitField: batched evaluation (reference grid path and OpenCL) against the brute-force sum,
// derivatives against finite differences, and the binary file format (round trip and corruption).
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <random>
#include <sstream>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/field.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

/// The OpenCL device `spec` opened with the environment variables `env` set (and unset again).
Device openWithEnv(const std::string& spec, const std::vector<std::pair<const char*, const char*>>& env) {
  for (const auto& [name, value] : env) setenv(name, value, 1);
  Device d = Device::open(spec);
  for (const auto& [name, value] : env) unsetenv(name);
  return d;
}

/// The OpenCL device `spec` opened with DUPLEXFIT_FIELD_KERNEL=`kernel` (vector8, vector16: the SIMD _v8
/// kernels 8 or 16 centres a step, a CPU device's default at its native width; scalar: one centre a step, a
/// GPU's).
Device openWithFieldKernel(const std::string& spec, const char* kernel) {
  return openWithEnv(spec, {{"DUPLEXFIT_FIELD_KERNEL", kernel}});
}

/// Runs `body` on the reference device and the OpenCL test device (when there is one) with each of its
/// two field kernels, in float and, where supported, double.
void forEachDeviceAndPrecision(const std::function<void(const Device&, Precision)>& body) {
  std::vector<Device> devices{Device::reference()};
  if (const Device* d = testing::openclTestDevice()) {
    for (const char* kernel : {"vector8", "vector16", "scalar"}) {
      devices.push_back(openWithFieldKernel(d->info().spec, kernel));
      const DeviceTuning t = devices.back().tuning();
      REQUIRE(t.fieldVector == (std::string(kernel) != "scalar"));
      REQUIRE(t.fieldWidth == (std::string(kernel) == "vector8" ? 8 : std::string(kernel) == "vector16" ? 16 : 1));
    }
  }
  for (const Device& d : devices) {
    for (const Precision p : {Precision::Float, Precision::Double}) {
      if (p == Precision::Double && !d.supportsDouble()) continue;
      CAPTURE(d.info().spec);
      CAPTURE(d.tuning().describe());
      CAPTURE(precisionName(p));
      body(d, p);
    }
  }
}

// A random three-level field in a box around the origin, with a non-trivial normalisation.
ImplicitField randomField(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5), w(-0.3, 0.3);
  std::vector<FieldLevel> levels;
  const int counts[3] = {20, 150, 1200};
  for (int k = 0; k < 3; ++k) {
    FieldLevel l;
    l.sigma = 0.6 / (1 << k);
    l.centres.resize(counts[k], 3);
    l.weights.resize(counts[k]);
    for (int j = 0; j < counts[k]; ++j) {
      l.centres.row(j) << u(rng), u(rng), u(rng);
      l.weights[j] = w(rng);
    }
    levels.push_back(std::move(l));
  }
  Normalization n;
  n.centre = Eigen::Vector3d(1.0, -2.0, 0.5);
  n.scale = 0.25;
  return ImplicitField(n, -1.0, std::move(levels), {0.1, -0.2}, Eigen::AlignedBox3d(Eigen::Vector3d(-1, -4, -1.5), Eigen::Vector3d(3, 0, 2.5)));
}

Points randomQueries(const ImplicitField& f, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-2.4, 2.4);  // world units: beyond the centres' box too
  Points q(n, 3);
  for (int i = 0; i < n; ++i) q.row(i) = f.normalization().centre.transpose() + Eigen::RowVector3d(u(rng), u(rng), u(rng));
  // Exactly at a centre of the finest level (ρ = 0 in the Hessian) and far away.
  q.row(0) = (f.levels()[2].centres.row(5) / f.normalization().scale) + f.normalization().centre.transpose();
  q.row(1) << 100.0, 100.0, 100.0;
  // At every centre of the finest level, when there is room: every cell's row ends there, the last
  // record of the device buffer included (the 8-wide kernels read up to 7 records past a row).
  const Eigen::Index m = f.levels()[2].centres.rows();
  if (n >= m + 10) {
    for (Eigen::Index j = 0; j < m; ++j) {
      q.row(2 + j) = (f.levels()[2].centres.row(j) / f.normalization().scale) + f.normalization().centre.transpose();
    }
  }
  return q;
}

/// n³ grid nodes over a cube of side 4 around f's centre (world units), in x-fastest order.
Points gridAround(const ImplicitField& f, int n) {
  Points grid(n * n * n, 3);
  for (int k = 0, r = 0; k < n; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i, ++r) {
        grid.row(r) = f.normalization().centre.transpose() + Eigen::RowVector3d(i, j, k) * (4.0 / n) - Eigen::RowVector3d(2, 2, 2);
      }
    }
  }
  return grid;
}

/// The rows of p in a random order (seeded): row r of the result is row perm[r] of p.
Points shuffledRows(const Points& p, unsigned seed, std::vector<Eigen::Index>& perm) {
  perm.resize(static_cast<std::size_t>(p.rows()));
  for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = static_cast<Eigen::Index>(i);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(seed));
  Points out(p.rows(), 3);
  for (Eigen::Index r = 0; r < p.rows(); ++r) out.row(r) = p.row(perm[static_cast<std::size_t>(r)]);
  return out;
}

/// `e` evaluates at q (with `derivatives`) exactly as a fresh evaluator of f's first `levels` levels.
void checkSameAsFresh(const FieldEvaluator& e, const ImplicitField& f, const Device& d, Precision p, int levels,
                      const Points& q, FieldDerivatives derivatives) {
  const FieldEvaluator fresh(d, f, p, levels);
  const FieldSamples a = e.evaluate(q, derivatives);
  const FieldSamples b = fresh.evaluate(q, derivatives);
  CHECK(a.values == b.values);
  CHECK(a.gradients == b.gradients);
  CHECK(a.hessians == b.hessians);
}

}  // namespace

TEST_SUITE("field") {
  TEST_CASE("field: gradient and Hessian agree with finite differences of the reference value") {
    const ImplicitField f = randomField(1);
    const Points q = randomQueries(f, 40, 2);
    const double h = 1e-5;
    for (Eigen::Index i = 2; i < q.rows(); ++i) {
      const Eigen::Vector3d x = q.row(i).transpose();
      const Eigen::Vector3d g = f.gradient(x);
      const Eigen::Matrix3d H = f.hessian(x);
      for (int a = 0; a < 3; ++a) {
        Eigen::Vector3d e = Eigen::Vector3d::Zero();
        e[a] = h;
        CHECK(g[a] == doctest::Approx((f.value(x + e) - f.value(x - e)) / (2 * h)).epsilon(1e-5).scale(1.0));
        const Eigen::Vector3d dg = (f.gradient(x + e) - f.gradient(x - e)) / (2 * h);
        for (int b = 0; b < 3; ++b) CHECK(H(b, a) == doctest::Approx(dg[b]).epsilon(1e-4).scale(1.0));
      }
    }
    // f → f0/scale far from every centre.
    CHECK(f.value(Eigen::Vector3d(100, 100, 100)) == doctest::Approx(-1.0 / 0.25));
  }

  TEST_CASE("field: batched evaluation on the reference and OpenCL devices matches the brute-force sum") {
    const ImplicitField f = randomField(3);
    const Points q = randomQueries(f, 3001, 4);
    // The brute-force sums, once for every device and precision.
    std::vector<double> fs(static_cast<std::size_t>(q.rows()));
    std::vector<Eigen::Vector3d> gs(fs.size());
    std::vector<Eigen::Matrix3d> hessians(fs.size());
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      const Eigen::Vector3d x = q.row(i).transpose();
      fs[static_cast<std::size_t>(i)] = f.value(x);
      gs[static_cast<std::size_t>(i)] = f.gradient(x);
      hessians[static_cast<std::size_t>(i)] = f.hessian(x);
    }
    forEachDeviceAndPrecision([&](const Device& d, Precision p) {
      const double tol = p == Precision::Double ? 1e-10 : 2e-4;
      const FieldSamples s = f.evaluate(d, q, FieldDerivatives::Hessian, p);
      const FieldSamples v = f.evaluate(d, q, FieldDerivatives::None, p);
      REQUIRE(s.values.size() == q.rows());
      int bad = 0;
      for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double fv = fs[static_cast<std::size_t>(i)];
        const Eigen::Vector3d& g = gs[static_cast<std::size_t>(i)];
        const Eigen::Matrix3d& H = hessians[static_cast<std::size_t>(i)];
        const double scale = 1.0 + std::abs(fv);
        if (std::abs(s.values[i] - fv) > tol * scale || std::abs(v.values[i] - fv) > tol * scale) ++bad;
        if ((s.gradients.row(i).transpose() - g).norm() > tol * (1.0 + g.norm()) * 10) ++bad;
        const double hs[6] = {H(0, 0), H(0, 1), H(0, 2), H(1, 1), H(1, 2), H(2, 2)};
        for (int c = 0; c < 6; ++c) {
          if (std::abs(s.hessians(i, c) - hs[c]) > tol * (1.0 + H.norm()) * 100) ++bad;
        }
      }
      CHECK(bad == 0);
    });
  }

  TEST_CASE("field: a batch in scattered order gets each point's values as in a coherent order") {
    // 40,000 queries (above the size where a scattered batch is evaluated in Morton order and put back) on a
    // grid in x-fastest order, and the same queries shuffled: every point's value and gradient the same, bit
    // for bit.
    const ImplicitField f = randomField(5);
    const Points grid = gridAround(f, 34);
    std::vector<Eigen::Index> perm;
    const Points shuffled = shuffledRows(grid, 11, perm);
    forEachDeviceAndPrecision([&](const Device& d, Precision p) {
      const FieldSamples a = f.evaluate(d, grid, FieldDerivatives::Gradient, p);
      const FieldSamples b = f.evaluate(d, shuffled, FieldDerivatives::Gradient, p);
      const FieldSamples c = f.evaluate(d, shuffled, FieldDerivatives::None, p);
      int differ = 0;
      for (Eigen::Index r = 0; r < grid.rows(); ++r) {
        const Eigen::Index i = perm[static_cast<std::size_t>(r)];
        if (b.values[r] != a.values[i] || c.values[r] != a.values[i] || b.gradients.row(r) != a.gradients.row(i)) ++differ;
      }
      CHECK(differ == 0);
      CHECK(a.values.cwiseAbs().maxCoeff() > 0.0);
    });
    // More than one chunk of 2^20 queries (each chunk judged and sorted on its own), on one device.
    const Points many = gridAround(f, 104);
    std::vector<Eigen::Index> manyPerm;
    const Points manyShuffled = shuffledRows(many, 12, manyPerm);
    const Device& d = testing::openclOrReferenceDevice();
    const Eigen::VectorXd inOrder = f.evaluate(d, many).values, scattered = f.evaluate(d, manyShuffled).values;
    int differ = 0;
    for (Eigen::Index r = 0; r < many.rows(); ++r) differ += scattered[r] != inOrder[manyPerm[static_cast<std::size_t>(r)]] ? 1 : 0;
    CHECK(many.rows() > (Eigen::Index{1} << 20));
    CHECK(differ == 0);
  }

  TEST_CASE("field: the tile kernels give a point the same bits in any batch, and the per-query kernels' sum") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    if (!dev.tuning().fieldVector) {
      MESSAGE("skipped: the test device runs the scalar field kernel (no tiles)");
      return;
    }
    // A field shaped like a fit's hierarchy (six levels, σ halving, the centres near a sphere of radius 0.4,
    // σ_1 = 1.09): the tile kernels sum its levels 1-4 a tile of 8 or 16 queries at a time.
    std::mt19937 rng(23);
    std::normal_distribution<double> g(0.0, 1.0);
    std::uniform_real_distribution<double> s(-1.0, 1.0);
    const int counts[6] = {24, 141, 857, 4000, 12000, 30000};
    std::vector<FieldLevel> levels;
    for (int k = 0; k < 6; ++k) {
      FieldLevel l;
      l.sigma = 1.09 / (1 << k);
      l.centres.resize(counts[k], 3);
      l.weights.resize(counts[k]);
      for (int j = 0; j < counts[k]; ++j) {
        const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
        l.centres.row(j) = ((0.4 + 0.3 * l.sigma * s(rng)) * d).transpose();
        l.weights[j] = (k < 2 ? 1.0 : 0.1) * s(rng);
      }
      levels.push_back(std::move(l));
    }
    const ImplicitField f(Normalization{}, -1.0, std::move(levels), {},
                          Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.5), Eigen::Vector3d::Constant(0.5)));
    // Queries as a mesh gives them: 20,000 points near the sphere in a spiral (neighbours in sequence).
    const int n = 20000;
    Points q(n, 3);
    for (int i = 0; i < n; ++i) {
      const double z = 1.0 - (2.0 * i + 1.0) / n, a = 2.399963229728653 * i, rho = std::sqrt(1.0 - z * z);
      q.row(i) << (0.4 + 0.01 * s(rng)) * rho * std::cos(a), (0.4 + 0.01 * s(rng)) * rho * std::sin(a), 0.4 * z;
    }
    std::vector<Eigen::Index> perm;
    const Points shuffled = shuffledRows(q, 29, perm);
    // Scattered: every 67th point (299, sorted in Morton order: each tile wider than the finer tiled levels'
    // σ) and every 211th (95, below the size sorted: tiles in the batch's own order).
    const auto strided = [&q](int step) {
      Points out((q.rows() + step - 1) / step, 3);
      for (Eigen::Index r = 0; r < out.rows(); ++r) out.row(r) = q.row(r * step);
      return out;
    };
    for (const char* kernel : {"vector8", "vector16"}) {
      CAPTURE(kernel);
      const Device tiles = openWithFieldKernel(dev.info().spec, kernel);
      const Device perQuery =
          openWithEnv(dev.info().spec, {{"DUPLEXFIT_FIELD_KERNEL", kernel}, {"DUPLEXFIT_FIELD_TILES", "0"}});
      REQUIRE(tiles.tuning().fieldTiles);
      CHECK(tiles.tuning().describe().find("+tiles") != std::string::npos);
      REQUIRE_FALSE(perQuery.tuning().fieldTiles);
      CHECK(perQuery.tuning().describe().find("+tiles") == std::string::npos);
      for (const FieldDerivatives d : {FieldDerivatives::None, FieldDerivatives::Gradient}) {
        const FieldSamples a = f.evaluate(tiles, q, d);
        const FieldSamples b = f.evaluate(tiles, shuffled, d);
        const FieldSamples ref = f.evaluate(perQuery, q, d);
        int differ = 0;
        for (Eigen::Index r = 0; r < q.rows(); ++r) {
          const Eigen::Index i = perm[static_cast<std::size_t>(r)];
          differ += b.values[r] != a.values[i] ||
                    (d == FieldDerivatives::Gradient && b.gradients.row(r) != a.gradients.row(i));
        }
        CHECK(differ == 0);
        for (const int step : {67, 211}) {
          CAPTURE(step);
          const FieldSamples c = f.evaluate(tiles, strided(step), d);
          int other = 0;
          for (Eigen::Index r = 0; r < c.values.rows(); ++r) {
            other += c.values[r] != a.values[r * step] ||
                     (d == FieldDerivatives::Gradient && c.gradients.row(r) != a.gradients.row(r * step));
          }
          CHECK(other == 0);
        }
        // A point alone (a tile of one query) and the per-query kernels (another order of the additions).
        double vs = 0.0, gs = 0.0;
        for (Eigen::Index r = 0; r < q.rows(); r += 997) {
          const FieldSamples one = f.evaluate(tiles, q.middleRows(r, 1), d);
          CHECK(one.values[0] == a.values[r]);
          if (d == FieldDerivatives::Gradient) CHECK(one.gradients.row(0) == a.gradients.row(r));
        }
        for (Eigen::Index r = 0; r < q.rows(); ++r) {
          vs = std::max(vs, std::abs(a.values[r] - ref.values[r]));
          if (d == FieldDerivatives::Gradient) gs = std::max(gs, (a.gradients.row(r) - ref.gradients.row(r)).norm());
        }
        CHECK(vs <= 1e-6);
        CHECK(gs <= 1e-4);
        // Against the brute-force sum in double.
        double exact = 0.0;
        for (Eigen::Index r = 0; r < q.rows(); r += 41) {
          exact = std::max(exact, std::abs(a.values[r] - f.value(q.row(r).transpose())));
        }
        CHECK(exact <= 1e-6);
        CHECK(a.values.cwiseAbs().maxCoeff() > 0.01);
      }
    }
    setenv("DUPLEXFIT_FIELD_TILES", "yes", 1);
    CHECK_THROWS_AS((void)Device::open(dev.info().spec), InvalidArgument);
    unsetenv("DUPLEXFIT_FIELD_TILES");
  }

  TEST_CASE("field: the SIMD kernel's width is the device's native float vector unless DUPLEXFIT_FIELD_KERNEL says") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const Device d = openWithFieldKernel(dev.info().spec, "vector");
    CHECK(d.tuning().fieldWidth == (dev.info().nativeFloatWidth >= 16 ? 16 : 8));
    if (dev.info().type == DeviceType::Cpu) {
      CHECK(dev.tuning().fieldVector);
      CHECK(dev.tuning().fieldWidth == d.tuning().fieldWidth);
      CHECK(dev.tuning().describe().find(" field=vector" + std::to_string(d.tuning().fieldWidth)) != std::string::npos);
    }
    const Device s = openWithFieldKernel(dev.info().spec, "scalar");
    CHECK(s.tuning().fieldWidth == 1);
    CHECK(s.tuning().describe().find(" field=scalar") != std::string::npos);
    setenv("DUPLEXFIT_FIELD_KERNEL", "vector32", 1);
    try {
      (void)Device::open(dev.info().spec);
      FAIL("DUPLEXFIT_FIELD_KERNEL=vector32 was accepted");
    } catch (const InvalidArgument& e) {
      CHECK(std::string(e.what()).find("DUPLEXFIT_FIELD_KERNEL='vector32'") != std::string::npos);
    }
    unsetenv("DUPLEXFIT_FIELD_KERNEL");
  }

  TEST_CASE("field: the SIMD kernels sum the coarse levels with large weights in double, within 1e-6 of the box") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    if (!dev.tuning().fieldVector || !dev.info().fp64) {
      MESSAGE("skipped: the test device runs the scalar field kernel or has no fp64");
      return;
    }
    // A field shaped like a fit's hierarchy in the unit box (fandisk_550k's: σ_1 = 1.09, weights up to
    // 2.95 and 1.26 at the two coarsest levels, a few tenths below): in float the coarse terms' rounding
    // alone is about 1e-7 |w| each.
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> u(-0.5, 0.5), s(-1.0, 1.0);
    const int counts[5] = {24, 141, 857, 4000, 12000};
    const double weights[5] = {3.0, 1.3, 0.2, 0.1, 0.05};
    std::vector<FieldLevel> levels;
    for (int k = 0; k < 5; ++k) {
      FieldLevel l;
      l.sigma = 1.09 / (1 << k);
      l.centres.resize(counts[k], 3);
      l.weights.resize(counts[k]);
      for (int j = 0; j < counts[k]; ++j) {
        l.centres.row(j) << u(rng), u(rng), u(rng);
        l.weights[j] = weights[k] * s(rng);
      }
      levels.push_back(std::move(l));
    }
    const ImplicitField f(Normalization{}, -1.0, std::move(levels), {},
                          Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-0.5), Eigen::Vector3d::Constant(0.5)));
    Points q(4000, 3);
    for (Eigen::Index i = 0; i < q.rows(); ++i) q.row(i) << u(rng), u(rng), u(rng);
    std::vector<double> exact(static_cast<std::size_t>(q.rows()));
    for (Eigen::Index i = 0; i < q.rows(); ++i) exact[static_cast<std::size_t>(i)] = f.value(q.row(i).transpose());
    const auto largestError = [&](const Device& d) {
      const Eigen::VectorXd v = f.evaluate(d, q, FieldDerivatives::None, Precision::Float).values;
      double e = 0.0;
      for (Eigen::Index i = 0; i < q.rows(); ++i) e = std::max(e, std::abs(v[i] - exact[static_cast<std::size_t>(i)]));
      return e;  // the box side is 1
    };
    for (const char* kernel : {"vector8", "vector16"}) {
      CAPTURE(kernel);
      const Device mixed = openWithFieldKernel(dev.info().spec, kernel);
      const Device plain =
          openWithEnv(dev.info().spec, {{"DUPLEXFIT_FIELD_KERNEL", kernel}, {"DUPLEXFIT_FIELD_COARSE", "float"}});
      REQUIRE(mixed.tuning().fieldCoarseDouble);
      CHECK(mixed.tuning().describe().find("+double") != std::string::npos);
      CHECK_FALSE(plain.tuning().fieldCoarseDouble);
      const double withDouble = largestError(mixed), inFloat = largestError(plain);
      MESSAGE("largest |f - f_exact|: " << withDouble << " with the coarse levels in double, " << inFloat << " in float");
      CHECK(withDouble <= 1e-6);
      CHECK(inFloat > 1e-6);  // what the double levels remove: the test can tell them apart
    }
    setenv("DUPLEXFIT_FIELD_COARSE", "half", 1);
    CHECK_THROWS_AS((void)Device::open(dev.info().spec), InvalidArgument);
    unsetenv("DUPLEXFIT_FIELD_COARSE");
  }

  TEST_CASE("field: levels too fine for a full cell table (wider x-cells, then deeper cells) match the brute-force sum") {
    // Clusters of centres spread over a large box with a small support: the evaluator's table of σ-deep,
    // σ/8-wide cells would pass 2^24 cells. Level 2 (σ = 0.004 over 1 × 1 × 0.26) fits with σ/4-wide
    // x-cells; level 3 (σ = 0.0015 over the unit cube) not even with σ-wide ones, so its cells grow in y and
    // z too. Each must still find every centre within the support.
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(-0.5, 0.5), w(-0.3, 0.3), unit(-1.0, 1.0);
    std::vector<FieldLevel> levels;
    FieldLevel coarse;
    coarse.sigma = 0.4;
    coarse.centres.resize(40, 3);
    coarse.weights.resize(40);
    for (int j = 0; j < 40; ++j) {
      coarse.centres.row(j) << u(rng), u(rng), u(rng);
      coarse.weights[j] = w(rng);
    }
    levels.push_back(coarse);
    Points seeds(0, 3);
    for (const auto& [sigma, zExtent] : {std::pair{0.004, 0.26}, std::pair{0.0015, 1.0}}) {
      const int clusters = 150, each = 12;
      FieldLevel l;
      l.sigma = sigma;
      l.centres.resize(clusters * each + 2, 3);
      l.weights.resize(clusters * each + 2);
      seeds.resize(clusters, 3);
      for (int c = 0; c < clusters; ++c) {
        seeds.row(c) << u(rng), u(rng), zExtent * u(rng);
        for (int j = 0; j < each; ++j) {
          l.centres.row(c * each + j) = seeds.row(c) + sigma * Eigen::RowVector3d(unit(rng), unit(rng), unit(rng));
          l.weights[c * each + j] = w(rng);
        }
      }
      // The box's corners.
      l.centres.row(clusters * each) << -0.5 - sigma, -0.5 - sigma, -0.5 * zExtent - sigma;
      l.centres.row(clusters * each + 1) << 0.5 + sigma, 0.5 + sigma, 0.5 * zExtent + sigma;
      l.weights.tail(2).setConstant(0.2);
      levels.push_back(std::move(l));
    }
    Normalization n;
    n.centre = Eigen::Vector3d(0.5, -1.0, 2.0);
    n.scale = 2.0;
    const ImplicitField f(n, -1.0, std::move(levels), {}, Eigen::AlignedBox3d(Eigen::Vector3d(0, -1.5, 1.5), Eigen::Vector3d(1, -0.5, 2.5)));
    // Queries within a support of the clusters of both fine levels, and at their centres.
    const int per = 4;
    Points q(2 * 150 * per, 3);
    Eigen::Index row = 0;
    for (std::size_t k = 1; k <= 2; ++k) {
      const FieldLevel& l = f.levels()[k];
      for (int c = 0; c < 150; ++c) {
        for (int j = 0; j < per; ++j) {
          const Eigen::RowVector3d x = j == 0 ? Eigen::RowVector3d(l.centres.row(c * 12))
                                              : Eigen::RowVector3d(l.centres.row(c * 12) +
                                                                   1.5 * l.sigma * Eigen::RowVector3d(unit(rng), unit(rng), unit(rng)));
          q.row(row++) = x / n.scale + n.centre.transpose();
        }
      }
    }
    std::vector<double> fs(static_cast<std::size_t>(q.rows()));
    std::vector<Eigen::Vector3d> gs(fs.size());
    for (Eigen::Index i = 0; i < q.rows(); ++i) {
      fs[static_cast<std::size_t>(i)] = f.value(q.row(i).transpose());
      gs[static_cast<std::size_t>(i)] = f.gradient(q.row(i).transpose());
    }
    forEachDeviceAndPrecision([&](const Device& d, Precision p) {
      const double tol = p == Precision::Double ? 1e-10 : 2e-4;
      const FieldSamples s = f.evaluate(d, q, FieldDerivatives::Gradient, p);
      int bad = 0;
      for (Eigen::Index i = 0; i < q.rows(); ++i) {
        const double fv = fs[static_cast<std::size_t>(i)];
        const Eigen::Vector3d& g = gs[static_cast<std::size_t>(i)];
        if (std::abs(s.values[i] - fv) > tol * (1.0 + std::abs(fv))) ++bad;
        if ((s.gradients.row(i).transpose() - g).norm() > tol * (1.0 + g.norm()) * 10) ++bad;
      }
      CHECK(bad == 0);
    });
  }

  TEST_CASE("field: a partial evaluator sums only the first levels") {
    const ImplicitField f = randomField(5);
    const Points q = randomQueries(f, 50, 6);
    const ImplicitField first(f.normalization(), f.f0(), {f.levels()[0]}, {}, f.bounds());
    const FieldEvaluator e(Device::reference(), f, Precision::Double, 1);
    const Eigen::VectorXd v = e.evaluate(q).values;
    for (Eigen::Index i = 0; i < q.rows(); ++i) CHECK(v[i] == doctest::Approx(first.value(q.row(i).transpose())));
  }

  TEST_CASE("field: an evaluator grown by appendLevel equals one built from the whole field") {
    // Levels of growing size, so that the device buffers are reallocated (and, between reallocations,
    // only the new level's tail is written): every intermediate state must equal a fresh evaluator of
    // the same levels, bit for bit, on the reference device and on OpenCL, in both precisions.
    const ImplicitField base = randomField(11);
    std::vector<FieldLevel> levels = base.levels();
    FieldLevel small;  // a 4th level smaller than the previous one: written into the existing buffers
    small.sigma = 0.05;
    small.centres = base.levels()[2].centres.topRows(30) * 0.9;
    small.weights = base.levels()[2].weights.head(30);
    levels.push_back(small);
    const ImplicitField f(base.normalization(), base.f0(), levels, base.offsets(), base.bounds());
    const Points q = randomQueries(f, 777, 12);
    forEachDeviceAndPrecision([&](const Device& d, Precision p) {
      FieldEvaluator grown(d, f.normalization(), f.f0(), p);
      CHECK(grown.levelCount() == 0);
      CHECK(grown.evaluate(q).values.cwiseEqual(f.f0() / f.normalization().scale).all());
      for (int k = 1; k <= 4; ++k) {
        grown.appendLevel(f.levels()[static_cast<std::size_t>(k - 1)]);
        CHECK(grown.levelCount() == k);
        checkSameAsFresh(grown, f, d, p, k, q, FieldDerivatives::Hessian);
      }
    });
  }

  TEST_CASE("field: dropLastLevel leaves the evaluator of the levels before it; a level appended after it counts") {
    // Down from four levels to none, each state bit for bit a fresh evaluator of the same levels (the
    // coarse levels summed in double on a CPU device included), then a different finest level in place of
    // the dropped one, as the fit's overshoot check does.
    const ImplicitField base = randomField(13);
    std::vector<FieldLevel> levels = base.levels();
    FieldLevel fourth;
    fourth.sigma = 0.08;
    fourth.centres = base.levels()[2].centres.topRows(400) * 0.95;
    fourth.weights = base.levels()[2].weights.head(400);
    levels.push_back(fourth);
    const ImplicitField f(base.normalization(), base.f0(), levels, base.offsets(), base.bounds());
    std::vector<FieldLevel> other = levels;
    other[3].weights *= -0.5;
    other[3].centres = other[3].centres.topRows(350).eval();
    other[3].weights = other[3].weights.head(350).eval();
    const ImplicitField g(base.normalization(), base.f0(), other, base.offsets(), base.bounds());
    const Points q = randomQueries(f, 901, 14);
    forEachDeviceAndPrecision([&](const Device& d, Precision p) {
      FieldEvaluator e(d, f, p);
      for (int k = 3; k >= 0; --k) {
        CAPTURE(k);
        e.dropLastLevel();
        CHECK(e.levelCount() == k);
        checkSameAsFresh(e, f, d, p, k, q, FieldDerivatives::Gradient);
      }
      CHECK_THROWS_AS(e.dropLastLevel(), InvalidArgument);
      for (int k = 0; k < 4; ++k) e.appendLevel(f.levels()[static_cast<std::size_t>(k)]);
      e.dropLastLevel();
      e.appendLevel(other[3]);
      const FieldEvaluator fresh(d, g, p);
      CHECK(e.evaluate(q).values == fresh.evaluate(q).values);
      CHECK(e.evaluateNormalized(q * 0.1) == fresh.evaluateNormalized(q * 0.1));
    });
  }

  TEST_CASE("field: save and load round trip evaluates identically; corrupt files are rejected") {
    const ImplicitField f = randomField(7);
    std::stringstream buffer;
    f.save(buffer);
    const std::string bytes = buffer.str();
    std::istringstream in(bytes);
    const ImplicitField g = ImplicitField::load(in, "mem");
    CHECK(g.levels().size() == 3);
    CHECK(g.offsets() == f.offsets());
    CHECK(g.normalization().scale == f.normalization().scale);
    const Points q = randomQueries(f, 100, 8);
    for (Eigen::Index i = 0; i < q.rows(); ++i) CHECK(g.value(q.row(i).transpose()) == f.value(q.row(i).transpose()));

    // Every truncation is an IoError naming the source, never a crash.
    for (std::size_t len = 0; len < bytes.size(); len += (len < 200 ? 1 : 997)) {
      std::istringstream t(bytes.substr(0, len));
      CHECK_THROWS_AS(ImplicitField::load(t, "cut.dxf"), IoError);
    }
    // A flipped bit in the payload fails the checksum.
    std::string flipped = bytes;
    flipped[bytes.size() / 2] = static_cast<char>(flipped[bytes.size() / 2] ^ 0x10);
    std::istringstream fb(flipped);
    CHECK_THROWS_AS(ImplicitField::load(fb, "flip.dxf"), IoError);
    // Unknown version and bad magic say so.
    std::string version = bytes;
    version[8] = 9;
    std::istringstream vb(version);
    try {
      (void)ImplicitField::load(vb, "v9.dxf");
      FAIL("expected IoError");
    } catch (const IoError& e) {
      CHECK(std::string(e.what()).find("version 9") != std::string::npos);
      CHECK(std::string(e.what()).find("v9.dxf") != std::string::npos);
    }
    std::istringstream junk("this is not a field file at all");
    CHECK_THROWS_AS(ImplicitField::load(junk, "junk"), IoError);
    CHECK_THROWS_AS(ImplicitField::load(std::string("/nonexistent/dir/x.dxf")), IoError);
  }

  TEST_CASE("field: a file with a valid checksum but an implausible box or non-finite numbers is rejected") {
    const ImplicitField f = randomField(7);
    const auto roundTrip = [](const ImplicitField& g) {
      std::stringstream buffer;
      g.save(buffer);
      std::istringstream in(buffer.str());
      return ImplicitField::load(in, "odd.dpxf");
    };
    const ImplicitField huge(f.normalization(), f.f0(), f.levels(), f.offsets(),
                             Eigen::AlignedBox3d(Eigen::Vector3d::Constant(-1e300), Eigen::Vector3d::Constant(1e300)));
    CHECK_THROWS_WITH_AS(roundTrip(huge), doctest::Contains("normalised units"), IoError);
    const ImplicitField inverted(f.normalization(), f.f0(), f.levels(), f.offsets(),
                                 Eigen::AlignedBox3d(Eigen::Vector3d::Constant(1.0), Eigen::Vector3d::Constant(-1.0)));
    CHECK_THROWS_WITH_AS(roundTrip(inverted), doctest::Contains("inverted"), IoError);
    std::vector<FieldLevel> levels = f.levels();
    levels[1].weights[0] = std::nan("");
    const ImplicitField nan(f.normalization(), f.f0(), levels, f.offsets(), f.bounds());
    CHECK_THROWS_WITH(roundTrip(nan), doctest::Contains("not finite"));  // the reader checks every number
    CHECK_NOTHROW(roundTrip(f));
  }
}
