// `--blocks N` in the library (docs/method.md, "Distributed fit"): N spatial blocks solved one after another
// in one process, without MPI. Every point is owned once, block by block; the field stays within the
// decomposition's error of the whole fit, and that error shrinks as the halo g grows; bad block counts
// and exact mode with blocks are refused. (N blocks against N MPI ranks: test/cli/test_cli_mpi.cpp.)
#include <doctest/doctest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <vector>

#include "duplexfit/communicator.hpp"
#include "duplexfit/distributed.hpp"
#include "duplexfit/error.hpp"
#include "fit/hierarchy.hpp"
#include "fit/partition.hpp"
#include "recording_interrupter.hpp"
#include "shapes.hpp"
#include "test_device.hpp"

using namespace duplexfit;

namespace {

double maxDifference(const ImplicitField& a, const ImplicitField& b, const PointSet& cloud) {
  double worst = 0.0;
  for (const double step : {0.0, 0.02, -0.02}) {
    const Points q = (cloud.positions() + step * cloud.normals()).eval();
    const Eigen::VectorXd fa = a.evaluate(Device::reference(), q, FieldDerivatives::None, Precision::Double).values;
    const Eigen::VectorXd fb = b.evaluate(Device::reference(), q, FieldDerivatives::None, Precision::Double).values;
    worst = std::max(worst, (fa - fb).cwiseAbs().maxCoeff());
  }
  return worst;
}

/// The blocks tests' cloud (3,000 points on a sphere of radius 0.5) and options: one offset, no sign
/// anchors (the decomposition's own error: anchors with blocks come from a proxy cloud), levels with more
/// than 600 points solved by blocks.
PointSet sphere3000() {
  Points normals;
  const Points p = testing::fibonacciSphere(3000, 0.5, &normals);
  return PointSet(p, normals);
}
FitOptions blocksFitOptions() {
  FitOptions o;
  o.offsets = {0.05};
  o.signAnchors = false;
  return o;
}
DistributedOptions blocksOptions() {
  DistributedOptions d;
  d.coarsePoints = 600;
  return d;
}

}  // namespace

TEST_SUITE("fit") {
  TEST_CASE("fit by blocks in one process: every point owned once, the whole fit within the halo's error, bad counts refused") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const PointSet cloud = sphere3000();
    const std::unique_ptr<Communicator> comm = makeSerialCommunicator();
    FitOptions o = blocksFitOptions();
    o.precision = Precision::Double;
    DistributedOptions d = blocksOptions();

    DistributedReport r1;
    const DistributedPoints one = partitionPoints(*comm, cloud, 0, 3000, r1, 1);
    REQUIRE(r1.ownedOnce);
    CHECK(r1.blocks == 1);
    const FitResult whole = fitDistributed(dev, *comm, one, o, d, r1);

    std::map<double, double> error;
    for (const double g : {1.0, 4.0}) {
      DistributedReport r;
      const DistributedPoints four = partitionPoints(*comm, cloud, 0, 3000, r, 4);
      REQUIRE(r.ownedOnce);
      CHECK(r.blocks == 4);
      CHECK(r.ranks == 1);
      REQUIRE(four.blockRows.size() == 5);
      CHECK(four.blockRows.front() == 0);
      CHECK(four.blockRows.back() == 3000);
      // Block by block: each point's Morton key lies in its block's range, and every block has points.
      // The fit's normalisation (scale = 1 / largest side, as fitDistributed computes it).
      const double scale = 1.0 / four.bounds.sizes().maxCoeff();
      const Points un = (scale * (four.points.positions().rowwise() - four.bounds.center().transpose())).eval();
      const detail::HierarchyBox box = detail::hierarchyBox(un);
      for (int b = 0; b < 4; ++b) {
        CHECK(four.blockRows[static_cast<std::size_t>(b) + 1] > four.blockRows[static_cast<std::size_t>(b)]);
        for (Eigen::Index i = four.blockRows[static_cast<std::size_t>(b)]; i < four.blockRows[static_cast<std::size_t>(b) + 1]; ++i) {
          REQUIRE(detail::ownerOfKey(four.blockSplitters, detail::mortonKey63(un.row(i).transpose(), box)) == b);
        }
      }
      d.halo = g;
      const FitResult blocks = fitDistributed(dev, *comm, four, o, d, r);
      REQUIRE(r.rankReports.size() == 4);
      std::size_t owned = 0;
      for (const DistributedRankReport& b : r.rankReports) {
        owned += b.points;
        CHECK(b.rank == 0);
        CHECK(b.peakBytes > 0);
        REQUIRE(b.levels.size() == blocks.report.levelReports.size());
      }
      CHECK(owned == 3000);
      // A block-solved level: every block solved a system, and their owned centres are the level's.
      bool someBlocked = false;
      for (std::size_t k = 0; k < blocks.report.levelReports.size(); ++k) {
        CHECK(blocks.report.levelReports[k].solve.converged);
        if (r.rankReports[0].levels[k].gathered) continue;
        someBlocked = true;
        std::size_t centres = 0;
        for (const DistributedRankReport& b : r.rankReports) {
          CHECK(b.levels[k].unknowns > 0);
          CHECK(b.levels[k].unknowns >= b.levels[k].ownedCentres);
          centres += b.levels[k].ownedCentres;
        }
        CHECK(centres == blocks.report.levelReports[k].centres);
      }
      CHECK(someBlocked);
      CHECK(blocks.report.levels == whole.report.levels);
      error[g] = maxDifference(blocks.field, whole.field, cloud);
      MESSAGE("4 blocks, g = " << g << ": max |f_blocks - f_whole| = " << error[g]);
    }
    CHECK(error[4.0] < error[1.0]);
    CHECK(error[4.0] < 1e-4);

    // Refused: fewer blocks than ranks (negative), too many, and exact mode with several blocks per rank.
    DistributedReport bad;
    CHECK_THROWS_AS(partitionPoints(*comm, cloud, 0, 3000, bad, -1), InvalidArgument);
    CHECK_THROWS_AS(partitionPoints(*comm, cloud, 0, 3000, bad, 1 << 20), InvalidArgument);
    DistributedReport r4;
    const DistributedPoints four = partitionPoints(*comm, cloud, 0, 3000, r4, 4);
    DistributedOptions exact = d;
    exact.mode = DistributedMode::Exact;
    CHECK_THROWS_AS(fitDistributed(dev, *comm, four, o, exact, r4), InvalidArgument);
  }

  TEST_CASE("fit by blocks: the fit's percent grows block by block to 100, and a block's solve can be cancelled") {
    DUPLEXFIT_OPENCL_DEVICE(dev);
    const PointSet cloud = sphere3000();
    const std::unique_ptr<Communicator> comm = makeSerialCommunicator();
    FitOptions o = blocksFitOptions();
    o.solver.progressInterval = 1;
    const DistributedOptions d = blocksOptions();
    DistributedReport r;
    const DistributedPoints four = partitionPoints(*comm, cloud, 0, 3000, r, 4);
    REQUIRE(r.ownedOnce);

    testing::RecordingInterrupter recorder;
    const FitResult fitted = fitDistributed(dev, *comm, four, o, d, r, nullptr, &recorder);
    std::vector<int> known;
    for (const int percent : recorder.percents) {
      if (percent >= 0) known.push_back(percent);
    }
    REQUIRE(known.size() >= 8);
    CHECK(std::is_sorted(known.begin(), known.end()));
    CHECK(known.front() <= 5);
    CHECK(known.back() == 100);
    // Within a block-solved level the percent moves on from block to block.
    bool blockSolved = false, iterationsCarryLevel = true;
    int levelOfBlocks = 0;
    for (std::size_t k = 0; k < r.rankReports[0].levels.size(); ++k) {
      if (!r.rankReports[0].levels[k].gathered) {
        blockSolved = true;
        levelOfBlocks = static_cast<int>(k) + 1;
      }
    }
    REQUIRE(blockSolved);
    for (const FitEvent& e : recorder.events) {
      if (e.stage == FitStage::Solve && e.iteration > 0 && e.level < 1) iterationsCarryLevel = false;
    }
    CHECK(iterationsCarryLevel);
    CHECK(fitted.report.levels == static_cast<int>(fitted.report.levelReports.size()));

    // Cancelled at the second CG iteration of the last block-solved level's third block.
    testing::RecordingInterrupter canceller;
    int blocksSeen = 0;
    canceller.stopWhen = [&](const testing::RecordingInterrupter& i) {
      const FitEvent& e = i.events.back();
      if (e.level != levelOfBlocks || e.stage != FitStage::Solve) return false;
      if (e.iteration == 0) return false;
      if (e.iteration == 1) ++blocksSeen;
      return blocksSeen == 3 && e.iteration >= 2;
    };
    DistributedReport rc;
    const DistributedPoints again = partitionPoints(*comm, cloud, 0, 3000, rc, 4);
    CHECK_THROWS_WITH_AS(fitDistributed(dev, *comm, again, o, d, rc, nullptr, &canceller),
                         doctest::Contains("solve of block 3"), Cancelled);
  }
}
