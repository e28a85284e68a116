// estimateNoise: the scatter of a cloud's points off their local planes in point spacings, against noise of a
// known size on a sphere, the shared clouds and their noisy twins, and what the fit does with a noisy cloud
// (filters it and fits it smoothly unless told not to) and says of it.
#include <doctest/doctest.h>

#include <filesystem>
#include <string>

#include "cli_runner.hpp"
#include "data.hpp"
#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/pipeline.hpp"
#include "duplexfit/preprocess.hpp"
#include "duplexfit/device.hpp"
#include "json_report.hpp"
#include "preprocess/preprocess_test_util.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using namespace duplexfit;

TEST_SUITE("preprocess") {
  TEST_CASE("noise: the ratio follows Gaussian noise of a known size on a sphere") {
    const NoiseEstimate clean = estimateNoise(testing::noisySphere(20000, 0.5, 0.0).positions());
    REQUIRE(clean.samples == 5000);
    CHECK(clean.ratio < 0.05);  // curvature only: h κ / 8-ish
    CHECK_FALSE(clean.noisy());
    const double h = clean.spacing;
    CHECK(h == doctest::Approx(0.0063).epsilon(0.1));  // about sqrt(4π r² / n)
    double last = clean.ratio;
    for (const double sigma : {0.1, 0.3, 0.6, 1.0}) {
      const NoiseEstimate e = estimateNoise(testing::noisySphere(20000, 0.5, sigma * h).positions());
      CAPTURE(sigma);
      CAPTURE(e.ratio);
      CHECK(e.ratio > last);  // grows with the noise
      last = e.ratio;
      // Noise of σ per coordinate is σ across the plane too, and it shortens the nearest-neighbour
      // distances a little: the ratio sits near σ / h, within a factor of two.
      CHECK(e.ratio > 0.5 * sigma);
      CHECK(e.ratio < 2.0 * sigma);
      CHECK(e.noisy() == (sigma >= 0.6));
    }
  }

  TEST_CASE("noise: a shared index gives the same estimate; duplicates do not zero the spacing") {
    const PointSet noisy = testing::noisySphere(8000, 0.5, 0.009);  // about 0.9 spacings
    const Points& p = noisy.positions();
    const NeighborIndex index(p);
    const NoiseEstimate own = estimateNoise(p), shared = estimateNoise(p, index);
    CHECK(shared.ratio == own.ratio);
    CHECK(shared.spacing == own.spacing);
    CHECK(shared.samples == own.samples);
    CHECK(own.noisy());
    // The outlier test on the same index: the same report as with its own tree.
    const OutlierReport a = findOutliers(p), b = findOutliers(p, {}, &index);
    CHECK(a.indices == b.indices);
    CHECK(a.medianNeighbourDistance == b.medianNeighbourDistance);
    // An index over other points is refused by both.
    const NeighborIndex other(p.topRows(100));
    CHECK_THROWS_AS(estimateNoise(p, other), InvalidArgument);
    CHECK_THROWS_AS(findOutliers(p, {}, &other), InvalidArgument);
    // Every point twice (duplicates not merged yet): the spacing skips the coincident twin.
    Points twice(2 * p.rows(), 3);
    twice.topRows(p.rows()) = p;
    twice.bottomRows(p.rows()) = p;
    const NoiseEstimate doubled = estimateNoise(twice);
    REQUIRE(doubled.samples > 0);
    CHECK(doubled.spacing == doctest::Approx(own.spacing).epsilon(0.15));
    CHECK(doubled.noisy());
  }

  TEST_CASE("noise: tiny clouds are not measured; bad options are refused") {
    Points p(5, 3);
    p << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1;
    const NoiseEstimate e = estimateNoise(p);
    CHECK(e.samples == 0);
    CHECK_FALSE(e.noisy());
    Points same = Points::Zero(50, 3);  // every point coincides: no spacing to measure by
    CHECK(estimateNoise(same).samples == 0);
    NoiseOptions o;
    o.neighbours = 3;
    CHECK_THROWS_AS(estimateNoise(p, o), InvalidArgument);
    o = NoiseOptions{};
    o.samples = 0;
    CHECK_THROWS_AS(estimateNoise(p, o), InvalidArgument);
    o = NoiseOptions{};
    o.threshold = -1.0;
    CHECK_THROWS_AS(estimateNoise(p, o), InvalidArgument);
  }

  TEST_CASE("noise: the shared clouds are clean and their 0.5% twins noisy") {
    DUPLEXFIT_SHARED_DATA_DIR(data);
    const auto measure = [&data](const std::string& name) {
      PointSet p = readPointCloud(data + "/clouds/" + name + ".ply");
      p.mergeDuplicates();
      return estimateNoise(p.positions());
    };
    // The clean clouds with the largest ratios (sharp rims between sparse rows, 180 points on a sphere) and
    // the noisy twins' clean originals.
    for (const std::string name : {"wheel_29k", "sphere_180", "armadillo_43k", "bunny_35k", "fandisk_50k",
                                   "thin_torus_20k"}) {
      const NoiseEstimate e = measure(name);
      CAPTURE(name);
      CAPTURE(e.ratio);
      CHECK(e.samples > 0);
      CHECK(e.ratio < 0.3);  // wheel_29k 0.22
      CHECK_FALSE(e.noisy());
    }
    for (const std::string name : {"bunny_35k_noise0.5pct", "fandisk_50k_noise0.5pct", "thin_torus_20k_noise0.5pct"}) {
      const NoiseEstimate e = measure(name);
      CAPTURE(name);
      CAPTURE(e.ratio);
      CHECK(e.ratio > 0.5);  // 0.59-0.64
      CHECK(e.noisy());
    }
  }

  TEST_CASE("noise: fit filters a noisy cloud and fits it smoothly, says so, and --no-denoise interpolates it") {
    DUPLEXFIT_REQUIRE_CLI();
    testing::TempDir dir("duplexfit-noise");
    const double h = estimateNoise(testing::noisySphere(1000, 0.5, 0.0).positions()).spacing;
    struct Case {
      double sigma;  // noise in point spacings
      std::string flags;
      bool denoised;     // the bilateral filter ran
      double smoothing;  // the fit's s
    };
    for (const Case& c : {Case{0.0, "", false, 0.0}, Case{0.8, "", true, 0.2}, Case{0.8, "--no-denoise", false, 0.0},
                          Case{0.8, "--smoothing 0.05", true, 0.05}, Case{0.0, "--denoise", true, 0.2}}) {
      CAPTURE(c.sigma);
      CAPTURE(c.flags);
      const fs::path cloud = dir.path() / "sphere.ply";
      writePointCloud(cloud.string(), testing::noisySphere(1000, 0.5, c.sigma * h));
      const fs::path out = dir.path() / "out";
      // A coarse grid without refinement: the interpolated noise would make millions of triangles (1000
      // points at σ = 0.8 spacings: 1.7M at the default grid), and only the log and the report are tested.
      const testing::CliRun run = testing::runCli("fit " + cloud.string() + " " + c.flags +
                                                  " --offset 0.05 --resolution 48 --refine-levels 0 --no-clean "
                                                  "--no-project -o " + out.string());
      CAPTURE(run.err);
      REQUIRE(run.status == 0);
      const bool noisy = c.sigma > 0.0;
      const bool told = run.err.find("the points scatter") != std::string::npos;
      CHECK(told == noisy);
      const bool hinted = run.err.find("hint: the points scatter") != std::string::npos;
      CHECK(hinted == (noisy && !c.denoised));
      if (hinted) CHECK(run.err.find("--denoise filters") != std::string::npos);
      if (noisy && c.denoised) CHECK(run.err.find("--no-denoise interpolates") != std::string::npos);
      CHECK((run.err.find("bilateral filter:") != std::string::npos) == c.denoised);
      const testing::Json report = testing::parseJson(testing::readFile(out / "report.json"));
      CHECK(report["preprocessing"]["noise"]["noisy"] == noisy);
      CHECK(report["preprocessing"]["noise"]["samples"] == 1000);
      CHECK(report["preprocessing"]["denoise"].is_null() == !c.denoised);
      if (c.denoised) {
        CHECK(report["preprocessing"]["denoise"]["reason"] ==
              (c.flags == "--denoise" ? "asked (--denoise)" : "noisy input (the noise estimate)"));
      }
      CHECK(report["smoothing"].get<double>() == doctest::Approx(c.smoothing));
      fs::remove_all(out);
    }
    const testing::CliRun both = testing::runCli("fit " + (dir.path() / "sphere.ply").string() +
                                                 " --denoise --no-denoise --offset 0.05 -o " + (dir.path() / "x").string());
    CHECK(both.status == 1);  // a usage error
    CHECK(both.err.find("--no-denoise") != std::string::npos);
    CHECK(!fs::exists(dir.path() / "x"));
  }

  TEST_CASE("noise: the pipeline filters a noisy cloud unless told not to, and fits a filtered one with denoiseSmoothing") {
    const Device d = Device::reference();
    const double h = estimateNoise(testing::noisySphere(600, 0.5, 0.0).positions()).spacing;
    const PointSet noisy = testing::noisySphere(600, 0.5, 0.8 * h);
    PipelineOptions o;
    o.fit.offsets = {0.05};
    o.surface.resolution = 32;
    o.surface.polygonize.refineLevels = 0;
    o.surface.finish.clean = false;
    o.surface.finish.project = false;
    o.surface.neckPassMaxFaces = 0;
    const PipelineReport on = runPipeline(d, noisy, o).report;
    CHECK(on.noise.noisy());
    CHECK(on.denoisedForNoise);
    REQUIRE(on.denoise.has_value());
    CHECK(on.denoise->moved > 0);
    CHECK(on.fit.smoothing == doctest::Approx(0.2));
    o.fit.smoothing = 0.1;
    CHECK(runPipeline(d, noisy, o).report.fit.smoothing == doctest::Approx(0.1));
    o.fit.smoothing = 0.0;
    o.denoiseSmoothing = 0.0;
    const PipelineReport plain = runPipeline(d, noisy, o).report;
    CHECK(plain.denoisedForNoise);
    CHECK(plain.fit.smoothing == 0.0);
    o.denoiseSmoothing = 0.2;
    o.denoiseWhenNoisy = false;
    const PipelineReport off = runPipeline(d, noisy, o).report;
    CHECK_FALSE(off.denoisedForNoise);
    CHECK_FALSE(off.denoise.has_value());
    CHECK(off.fit.smoothing == 0.0);
    o.denoiseWhenNoisy = true;
    const PipelineReport clean = runPipeline(d, testing::noisySphere(600, 0.5, 0.0), o).report;
    CHECK_FALSE(clean.noise.noisy());
    CHECK_FALSE(clean.denoisedForNoise);
    CHECK_FALSE(clean.denoise.has_value());
    CHECK(clean.fit.smoothing == 0.0);
    o.denoise = true;  // asked: filtered and fitted with denoiseSmoothing, noisy or not
    const PipelineReport asked = runPipeline(d, testing::noisySphere(600, 0.5, 0.0), o).report;
    CHECK_FALSE(asked.denoisedForNoise);
    CHECK(asked.denoise.has_value());
    CHECK(asked.fit.smoothing == doctest::Approx(0.2));
  }
}
