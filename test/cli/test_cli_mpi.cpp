// The distributed fit (docs/method.md, "Distributed fit") run as users run it: `mpirun -np P duplexfit fit`
// on a generated sphere. One rank gives the serial field's bytes; every point is owned once; local mode's
// error against one rank shrinks as the halo g grows; the meshes stay watertight with the same components;
// two runs at P = 4 give identical bytes; a bad input stops every rank. Skipped without MPI or mpirun.
// Also the partition's splitters (in-process, with a communicator that plays P ranks holding every key).
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>

#include "cli_runner.hpp"
#include "data.hpp"
#include "duplexfit/communicator.hpp"
#include "duplexfit/field.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/mesh.hpp"
#include "duplexfit/point_set.hpp"
#include "fit/partition.hpp"
#include "json_report.hpp"
#include "polygonize/mesh_checks.hpp"
#include "shapes.hpp"
#include "temp_dir.hpp"

namespace fs = std::filesystem;
using namespace duplexfit;

namespace {

using testing::CliRun;
using testing::Json;

// One process standing in for P ranks of which it is rank 0 and holds all the keys: reductions are the
// identity, so balancedSplitters sees the global histogram.
class PretendRanks final : public Communicator {
 public:
  explicit PretendRanks(int p) : p_(p) {}
  int rank() const noexcept override { return 0; }
  int size() const noexcept override { return p_; }
  std::string name() const override { return "pretend"; }
  void barrier() override {}
  void allreduce(double*, std::size_t, ReduceOp) override {}
  void allreduce(std::int64_t*, std::size_t, ReduceOp) override {}
  std::vector<unsigned char> allgatherv(const void*, std::size_t, std::vector<std::size_t>*) override { return {}; }
  std::vector<unsigned char> alltoallv(const std::vector<std::vector<unsigned char>>&, std::vector<std::size_t>&) override {
    return {};
  }
  void broadcast(void*, std::size_t, int) override {}
  [[noreturn]] void abort(int code) override { std::exit(code); }

 private:
  int p_;
};

std::string mpirunPrefix() {
  return "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 "
         "POCL_MAX_PTHREAD_COUNT=1 OMP_NUM_THREADS=1 mpirun --oversubscribe -x POCL_MAX_PTHREAD_COUNT -x OMP_NUM_THREADS ";
}

bool haveMpirun() { return testing::runCommand("command -v mpirun >/dev/null 2>&1").status == 0; }

// Max |f_a − f_b| (input units) at the cloud's points and at points `step` inside and outside them.
double maxDifference(const ImplicitField& a, const ImplicitField& b, const PointSet& cloud, double step0 = 0.02) {
  double worst = 0.0;
  for (const double step : {0.0, step0, -step0}) {
    const Points q = (cloud.positions() + step * cloud.normals()).eval();
    const Eigen::VectorXd fa = a.evaluate(Device::reference(), q, FieldDerivatives::None, Precision::Double).values;
    const Eigen::VectorXd fb = b.evaluate(Device::reference(), q, FieldDerivatives::None, Precision::Double).values;
    worst = std::max(worst, (fa - fb).cwiseAbs().maxCoeff());
  }
  return worst;
}

// The 6,000-point sphere of radius 0.5 the local-mode and blocks tests fit.
PointSet sphereCloud() {
  Points normals;
  const Points p = testing::fibonacciSphere(6000, 0.5, &normals);
  return PointSet(p, normals);
}

// `mpirun -np P duplexfit <common> <extra> -o dir/out` (P = 0: duplexfit alone, without mpirun); requires
// exit status 0 and returns the report.
Json runFit(const fs::path& dir, int ranks, const std::string& common, const std::string& extra, const std::string& out) {
  const std::string launch = ranks > 0 ? mpirunPrefix() + "-np " + std::to_string(ranks) + " " : std::string();
  const CliRun r = testing::runCommand(launch + testing::cliPath() + " " + common + " " + extra + " -o " +
                                       (dir / out).string() + " 2>&1");
  INFO(r.out << r.err);
  REQUIRE(r.status == 0);
  return testing::readJsonFile(dir / out / "report.json");
}

ImplicitField fieldOf(const fs::path& dir, const std::string& out) {
  return ImplicitField::load((dir / out / "field.dpxf").string());
}

// Both reports' meshes watertight, with the same components (and Euler characteristics: genus).
void checkSameTopology(const Json& rep, const Json& reference, bool euler) {
  REQUIRE(rep["meshes"].size() == reference["meshes"].size());
  for (std::size_t s = 0; s < rep["meshes"].size(); ++s) {
    CHECK(rep["meshes"][s]["topology"]["watertight"].get<bool>());
    CHECK(rep["meshes"][s]["topology"]["components"] == reference["meshes"][s]["topology"]["components"]);
    if (euler) {
      CHECK(rep["meshes"][s]["topology"]["euler_characteristic"] == reference["meshes"][s]["topology"]["euler_characteristic"]);
    }
  }
}

// A number as text that reads back to the same double.
std::string exactText(double x) {
  std::ostringstream s;
  s.precision(17);
  s << x;
  return s.str();
}

}  // namespace

// At the top of a test case that runs the CLI under mpirun: skips without the CLI, MPI or mpirun, and in the
// sanitizer build (Open MPI's own allocations are reported as leaks by LeakSanitizer; the Release suite
// runs these).
#ifdef DUPLEXFIT_SANITIZED
#define DUPLEXFIT_SKIP_IF_SANITIZED() \
  DUPLEXFIT_SKIP("Open MPI's own allocations are reported as leaks by LeakSanitizer; the Release suite runs it")
#else
#define DUPLEXFIT_SKIP_IF_SANITIZED() (void)0
#endif
#define DUPLEXFIT_REQUIRE_MPIRUN()                                                                      \
  DUPLEXFIT_REQUIRE_CLI();                                                                              \
  if (!mpiBuilt()) DUPLEXFIT_SKIP("this build has no MPI (DUPLEXFIT_WITH_MPI=OFF or MPI not found)");  \
  if (!haveMpirun()) DUPLEXFIT_SKIP("mpirun is not installed (Debian: openmpi-bin)");                  \
  DUPLEXFIT_SKIP_IF_SANITIZED()

TEST_SUITE("mpi") {
  TEST_CASE("partition: Morton ranges cover every key once, balanced within one histogram bucket") {
    Points normals;
    const Points p = testing::sampledTorus(20000, 0.35, 0.1, &normals);
    detail::HierarchyBox box = detail::hierarchyBox(p);
    std::vector<std::uint64_t> keys;
    for (Eigen::Index i = 0; i < p.rows(); ++i) keys.push_back(detail::mortonKey63(p.row(i).transpose(), box));
    for (const int ranks : {1, 2, 3, 4, 7}) {
      PretendRanks comm(ranks);
      const int bits = 12;
      const std::vector<std::uint64_t> s = detail::balancedSplitters(comm, keys, bits);
      REQUIRE(s.size() == static_cast<std::size_t>(ranks) + 1);
      CHECK(s.front() == 0);
      CHECK(s.back() == std::uint64_t{1} << 63);
      for (std::size_t r = 1; r < s.size(); ++r) CHECK(s[r - 1] <= s[r]);
      std::vector<std::size_t> count(static_cast<std::size_t>(ranks), 0);
      std::map<std::uint64_t, std::size_t> bucket;
      for (const std::uint64_t k : keys) {
        const int owner = detail::ownerOfKey(s, k);
        REQUIRE(owner >= 0);
        REQUIRE(owner < ranks);
        CHECK(k >= s[static_cast<std::size_t>(owner)]);
        CHECK(k < s[static_cast<std::size_t>(owner) + 1]);
        ++count[static_cast<std::size_t>(owner)];
        ++bucket[k >> (63 - bits)];
      }
      std::size_t total = 0, largestBucket = 0;
      for (const std::size_t c : count) total += c;
      for (const auto& [b, c] : bucket) largestBucket = std::max(largestBucket, c);
      CHECK(total == keys.size());
      const double ideal = static_cast<double>(keys.size()) / ranks;
      for (const std::size_t c : count) CHECK(std::abs(static_cast<double>(c) - ideal) <= static_cast<double>(largestBucket));
    }
  }

  TEST_CASE("mpirun duplexfit fit: P = 1 is the serial fit, every point owned once, local mode's error shrinks with g") {
    DUPLEXFIT_REQUIRE_MPIRUN();
    const fs::path dir = testing::scratchDir("mpi", "sphere");
    const PointSet cloud = sphereCloud();
    const fs::path input = dir / "sphere_6k.ply";
    writePointCloud(input.string(), cloud);
    const std::string common = " fit " + input.string() + " --offset 0.05 --resolution 48 --quiet";
    // The g runs solve every level to the CG tolerance (--coarse-tol 1e-6): with the default 1e-3 any two
    // correct fits differ by about 5e-6 between the centres, and local mode reaches that floor at g = 2.
    auto run = [&](int ranks, const std::string& extra, const std::string& out) {
      return runFit(dir, ranks, common.substr(1) + " --coarse-points 1200", extra, out);
    };
    // Serial (no MPI) and one rank distributed.
    const CliRun serial = testing::runCli(common.substr(1) + " -o " + (dir / "serial").string());
    INFO(serial.err);
    REQUIRE(serial.status == 0);
    const Json one = run(1, "--distributed local", "p1");
    CHECK(testing::readFile(dir / "serial" / "field.dpxf") == testing::readFile(dir / "p1" / "field.dpxf"));
    CHECK(one["distributed"]["owned_once"].get<bool>());
    // The decomposition's own error: without sign anchors (with P > 1 they come from a proxy cloud on the
    // gathered levels only, an error of its own that g does not change; measured below).
    run(1, "--distributed local --no-anchors --coarse-tol 1e-6", "p1_noanchors");
    const ImplicitField f1 = ImplicitField::load((dir / "p1_noanchors" / "field.dpxf").string());

    // P = 2 and 4 at g = 1, 2, 4; the error against one rank at near-surface points.
    std::map<std::pair<int, int>, double> error;
    for (const int ranks : {2, 4}) {
      for (const int g : {1, 2, 4}) {
        const std::string out = "p" + std::to_string(ranks) + "_g" + std::to_string(g);
        const Json rep = run(ranks, "--no-anchors --coarse-tol 1e-6 --halo " + std::to_string(g), out);
        CHECK(rep["distributed"]["owned_once"].get<bool>());
        CHECK(rep["distributed"]["ranks"].get<int>() == ranks);
        CHECK(rep["distributed"]["mode"].get<std::string>() == "local");
        CHECK(rep["distributed"]["per_rank"].size() == static_cast<std::size_t>(ranks));
        std::size_t owned = 0;
        for (const Json& r : rep["distributed"]["per_rank"]) owned += r["points"].get<std::size_t>();
        CHECK(owned == 6000);
        CHECK(rep["levels"].get<int>() == one["levels"].get<int>());
        const ImplicitField f = ImplicitField::load((dir / out / "field.dpxf").string());
        error[{ranks, g}] = maxDifference(f, f1, cloud);
        MESSAGE("P = " << ranks << ", g = " << g << ": max |f_P - f_1| = " << error[{ranks, g}]);
        // Watertight meshes with the same component counts as one rank.
        REQUIRE(rep["meshes"].size() == 2);
        checkSameTopology(rep, one, false);
      }
      CHECK(error[{ranks, 2}] < error[{ranks, 1}]);
      CHECK(error[{ranks, 4}] < error[{ranks, 2}]);
      CHECK(error[{ranks, 2}] < 1e-4);  // measured 2.7e-6 (P = 2) and 2.9e-6 (P = 4); g = 4: 7.8e-7, 1.2e-6
    }
    // With the sign anchors (the default): the proxy's effect, and two runs at P = 4 give identical bytes.
    const Json withAnchors = run(4, "--halo 2", "p4_anchors");
    run(4, "--halo 2", "p4_again");
    CHECK(testing::readFile(dir / "p4_anchors" / "field.dpxf") == testing::readFile(dir / "p4_again" / "field.dpxf"));
    CHECK(testing::readFile(dir / "p4_anchors" / "zero.ply") == testing::readFile(dir / "p4_again" / "zero.ply"));
    const double anchorError = maxDifference(ImplicitField::load((dir / "p4_anchors" / "field.dpxf").string()),
                                             ImplicitField::load((dir / "p1" / "field.dpxf").string()), cloud);
    MESSAGE("P = 4, g = 2, with sign anchors: max |f_P - f_1| = " << anchorError);
    CHECK(anchorError < 2e-3);  // measured 3.0e-4
    CHECK(withAnchors["distributed"]["winding_proxy_points"].get<int>() > 0);
  }

  TEST_CASE("mpirun duplexfit fit --distributed exact: the single-process field within 10x the CG tolerance at P = 2, 4") {
    DUPLEXFIT_REQUIRE_MPIRUN();
    DUPLEXFIT_SHARED_DATA_DIR(data);
    const fs::path dir = testing::scratchDir("mpi", "exact");
    const fs::path input = fs::path(data) / "clouds" / "fandisk_8k.ply";
    const PointSet cloud = readPointCloud(input.string());
    const double side = cloud.bounds().sizes().maxCoeff();
    // Without sign anchors: with P > 1 those of the distributed levels are not added (they need the whole
    // cloud's winding number), so the global systems are the serial ones only without them. Every level
    // solved to the CG tolerance (--coarse-tol 1e-6): with the default 1e-3 the levels below the finest
    // stop early, and any two correct solvers (the serial fit in float and in double, say) differ by
    // more than the finest level's tolerance between the centres (measured below).
    const std::string defaults = " fit " + input.string() + " --offset-rel 0.02 --no-anchors --resolution 64 --quiet";
    std::string common = defaults + " --coarse-tol 1e-6";
    auto run = [&](int ranks, const std::string& extra, const std::string& out) {
      return runFit(dir, ranks, common.substr(1) + " --coarse-points 1500", extra, out);
    };
    const CliRun serial = testing::runCli(common.substr(1) + " -o " + (dir / "serial").string());
    INFO(serial.err);
    REQUIRE(serial.status == 0);
    const CliRun serialDefault = testing::runCli(defaults.substr(1) + " -o " + (dir / "serial_default").string());
    REQUIRE(serialDefault.status == 0);
    const Json one = testing::readJsonFile(dir / "serial" / "report.json");
    const ImplicitField f1 = ImplicitField::load((dir / "serial" / "field.dpxf").string());
    // The CG tolerance: every level stops at max_i |r_i| ≤ 1e-6 (normalised, FitOptions::levelTolerance)
    // at the latest; in input units 1e-6 × the largest side.
    const double cgTolerance = 1e-6 * side;
    const double step = 0.005 * side;  // near-surface samples: the points and ±σ_M/4 or so along the normals
    for (const int ranks : {2, 4}) {
      const std::string out = "exact_p" + std::to_string(ranks);
      const Json rep = run(ranks, "--distributed exact", out);
      const Json& d = rep["distributed"];
      CHECK(d["mode"].get<std::string>() == "exact");
      CHECK(d["owned_once"].get<bool>());
      REQUIRE(d["per_rank"].size() == static_cast<std::size_t>(ranks));
      REQUIRE(rep["levels"].get<int>() == one["levels"].get<int>());
      // The same global systems: per level the serial fit's centres and non-zeros.
      for (std::size_t k = 0; k < rep["level_reports"].size(); ++k) {
        CHECK(rep["level_reports"][k]["centres"] == one["level_reports"][k]["centres"]);
        CHECK(rep["level_reports"][k]["nonzeros"] == one["level_reports"][k]["nonzeros"]);
        CHECK(rep["level_reports"][k]["cg"]["converged"].get<bool>());
      }
      // Per rank and distributed level: its rows, ghosts, non-zeros, CG iterations (one global count),
      // bytes and seconds; the ranks' rows add up to the level's unknowns.
      const std::size_t levels = d["per_rank"][0]["levels"].size();
      int distributedLevels = 0;
      for (std::size_t k = 0; k < levels; ++k) {
        if (d["per_rank"][0]["levels"][k]["gathered"].get<bool>()) continue;
        ++distributedLevels;
        std::size_t rows = 0;
        for (const Json& r : d["per_rank"]) {
          const Json& l = r["levels"][k];
          rows += l["unknowns"].get<std::size_t>();
          CHECK(l["ghosts"].get<std::size_t>() > 0);
          CHECK(l["bytes_received"].get<std::uint64_t>() > 0);
          CHECK(l["non_zeros"].get<std::size_t>() > 0);
          CHECK(l["cg_iterations"] == d["per_rank"][0]["levels"][k]["cg_iterations"]);
          MESSAGE("P = " << ranks << " level " << l["level"] << " rank " << r["rank"] << ": " << l["unknowns"] << " unknowns, "
                         << l["ghosts"] << " ghosts, " << l["non_zeros"] << " non-zeros, " << l["cg_iterations"]
                         << " CG iterations, " << l["bytes_received"] << " bytes received, " << l["seconds_solve"]
                         << " s solve");
        }
        CHECK(rows == rep["level_reports"][k]["centres"].get<std::size_t>());
      }
      CHECK(distributedLevels >= 2);
      const double error = maxDifference(ImplicitField::load((dir / out / "field.dpxf").string()), f1, cloud, step);
      MESSAGE("P = " << ranks << " exact: max |f_P - f_1| = " << error << " (CG tolerance " << cgTolerance << ")");
      CHECK(error <= 10.0 * cgTolerance);
      // Watertight meshes with the serial fit's components and Euler characteristics (genus).
      checkSameTopology(rep, one, true);
    }
    // Two runs at P = 4: identical bytes.
    run(4, "--distributed exact", "exact_p4_again");
    CHECK(testing::readFile(dir / "exact_p4" / "field.dpxf") == testing::readFile(dir / "exact_p4_again" / "field.dpxf"));

    // The default coarse tolerance, for the record (docs/method.md): the serial fit's own distance from
    // its tight-tolerance field, exact mode's and local mode's (g = 1, 2, 4) from the serial default fit.
    common = defaults;
    const ImplicitField f1Default = ImplicitField::load((dir / "serial_default" / "field.dpxf").string());
    const double serialSlack = maxDifference(f1Default, f1, cloud, step);
    MESSAGE("default coarse tolerance: serial vs serial with --coarse-tol 1e-6: " << serialSlack);
    run(4, "--distributed exact", "exact_p4_default");
    const double exactDefault = maxDifference(ImplicitField::load((dir / "exact_p4_default" / "field.dpxf").string()), f1Default, cloud, step);
    MESSAGE("default coarse tolerance: P = 4 exact: max |f_P - f_1| = " << exactDefault);
    CHECK(exactDefault < 1e-4);  // measured 2.5e-5 (the serial fit's own slack 9.3e-6)
    std::map<int, double> local;
    for (const int g : {1, 2, 4}) {
      const std::string out = "local_p4_g" + std::to_string(g);
      run(4, "--distributed local --halo " + std::to_string(g), out);
      local[g] = maxDifference(ImplicitField::load((dir / out / "field.dpxf").string()), f1Default, cloud, step);
      MESSAGE("default coarse tolerance: P = 4 local, g = " << g << ": max |f_P - f_1| = " << local[g]);
    }
    CHECK(local[2] < local[1]);
    CHECK(local[4] < local[2]);
  }

  TEST_CASE("mpirun duplexfit fit: each rank extracts a slab of the grid; welded, they are one process's meshes") {
    DUPLEXFIT_REQUIRE_MPIRUN();
    DUPLEXFIT_SHARED_DATA_DIR(data);
    const fs::path dir = testing::scratchDir("mpi", "slabs");
    const fs::path input = fs::path(data) / "clouds" / "fandisk_8k.ply";
    // Meshes as extracted (no cleaning or projection, which may order their work by vertex index).
    const Json rep = runFit(dir, 3, "fit " + input.string() + " --offset-rel 0.02 --resolution 96 --no-clean --no-project --quiet",
                            "--distributed exact", "p3");
    const Json& x = rep["distributed"]["extraction"];
    REQUIRE(x["per_rank"].size() == 3);
    // The slabs tile the grid's cells along z, each with triangles, its nodes and bytes.
    int next = 0;
    std::int64_t triangles = 0;
    for (const Json& r : x["per_rank"]) {
      CHECK(r["slab"][0].get<int>() == next);
      next = r["slab"][1].get<int>();
      CHECK(r["triangles"].get<std::int64_t>() > 0);
      CHECK(r["evaluated_nodes"].get<std::int64_t>() > 0);
      if (r["rank"].get<int>() > 0) CHECK(r["bytes_sent"].get<std::uint64_t>() > 0);
      triangles += r["triangles"].get<std::int64_t>();
      MESSAGE("rank " << r["rank"] << ": cells [" << r["slab"][0] << ", " << r["slab"][1] << "), " << r["triangles"]
                      << " triangles, " << r["evaluated_nodes"] << " nodes, " << r["refined_cells"] << " refined cells, "
                      << r["seconds"] << " s");
    }
    CHECK(next == rep["grid"]["nz"].get<int>());
    CHECK(triangles == rep["meshes"][0]["topology"]["faces"].get<std::int64_t>() +
                           rep["meshes"][1]["topology"]["faces"].get<std::int64_t>());
    // One process meshing the same field on the same grid: the same triangles.
    const std::string cell = exactText(rep["grid"]["cell"].get<double>());
    for (const auto& [iso, name] : {std::pair<std::string, std::string>{"0", "zero"}, {"", "offset1"}}) {
      CAPTURE(name);
      const std::string level = iso.empty() ? exactText(rep["offsets"][0].get<double>()) : iso;
      const fs::path one = dir / ("one_" + name + ".ply");
      const CliRun m = testing::runCli("mesh " + (dir / "p3" / "field.dpxf").string() + " --iso " + level + " --cell " + cell +
                                       " --no-clean --no-project --min-component " + (iso.empty() ? "0.001" : "0") +
                                       " --quiet -o " + one.string());
      INFO(m.err);
      REQUIRE(m.status == 0);
      const Mesh a = readMesh((dir / "p3" / (name + ".ply")).string()), b = readMesh(one.string());
      CHECK(a.faces.rows() == b.faces.rows());
      CHECK(a.vertices.rows() == b.vertices.rows());
      CHECK(testing::polygonize::sortedTriangles(a) == testing::polygonize::sortedTriangles(b));
      CHECK(rep["meshes"][name == "zero" ? 0 : 1]["topology"]["watertight"].get<bool>());
    }
  }

  TEST_CASE("duplexfit fit --blocks N: N blocks in one process are N ranks' fit; under mpirun the ranks share them") {
    DUPLEXFIT_REQUIRE_MPIRUN();
    const fs::path dir = testing::scratchDir("mpi", "blocks");
    const PointSet cloud = sphereCloud();
    const fs::path input = dir / "sphere_6k.ply";
    writePointCloud(input.string(), cloud);
    const std::string common = "fit " + input.string() + " --offset 0.05 --resolution 48 --quiet --coarse-points 1200 --halo 2";
    // 8 blocks in one process (no mpirun), 8 ranks, and 2 ranks holding 4 blocks each.
    const Json b8 = runFit(dir, 0, common, "--blocks 8", "b8");
    const Json p8 = runFit(dir, 8, common, "", "p8");
    const Json p2b8 = runFit(dir, 2, common, "--blocks 8", "p2b8");
    const ImplicitField fb8 = fieldOf(dir, "b8"), fp8 = fieldOf(dir, "p8"), fp2b8 = fieldOf(dir, "p2b8");
    // Within 10x the CG tolerance (1e-6 of the largest side, 1 here) of each other: the same blocks,
    // halos and rules; only the order of some sums differs (the reductions of MPI).
    const double cgTolerance = 1e-6;
    const double blocksVsRanks = maxDifference(fb8, fp8, cloud), sharedVsRanks = maxDifference(fp2b8, fp8, cloud);
    MESSAGE("8 blocks in one process vs 8 ranks: max |f - f| = " << blocksVsRanks << "; 2 ranks x 4 blocks: " << sharedVsRanks);
    CHECK(blocksVsRanks <= 10.0 * cgTolerance);
    CHECK(sharedVsRanks <= 10.0 * cgTolerance);
    checkSameTopology(b8, p8, true);
    checkSameTopology(p2b8, p8, true);
    for (const Json* rep : {&b8, &p2b8}) {
      const Json& d = (*rep)["distributed"];
      CHECK(d["blocks"].get<int>() == 8);
      CHECK(d["owned_once"].get<bool>());
      REQUIRE(d["per_block"].size() == 8);
      std::size_t owned = 0;
      for (std::size_t b = 0; b < 8; ++b) {
        const Json& block = d["per_block"][b];
        CHECK(block["block"].get<std::size_t>() == b);
        CHECK(block["unknowns"].get<std::size_t>() > 0);
        CHECK(block["peak_bytes"].get<std::uint64_t>() > 0);
        owned += block["points"].get<std::size_t>();
      }
      CHECK(owned == 6000);
    }
    CHECK(b8["distributed"]["ranks"].get<int>() == 1);
    REQUIRE(b8["distributed"]["per_rank"].size() == 1);
    CHECK(b8["distributed"]["per_rank"][0]["blocks"].get<int>() == 8);
    REQUIRE(p2b8["distributed"]["per_rank"].size() == 2);
    for (const Json& r : p2b8["distributed"]["per_rank"]) CHECK(r["blocks"].get<int>() == 4);
    CHECK(p8["distributed"]["blocks"].get<int>() == 8);
    // Block by block the same decomposition: per block and level the same unknowns as the rank's.
    for (std::size_t b = 0; b < 8; ++b) {
      const Json& lb = b8["distributed"]["per_block"][b]["levels"];
      const Json& lp = p8["distributed"]["per_block"][b]["levels"];
      REQUIRE(lb.size() == lp.size());
      for (std::size_t k = 0; k < lb.size(); ++k) {
        if (lb[k]["gathered"].get<bool>()) continue;
        CHECK(lb[k]["unknowns"] == lp[k]["unknowns"]);
        CHECK(lb[k]["owned_centres"] == lp[k]["owned_centres"]);
      }
    }

    // Refused, with nothing written: --blocks 0, --blocks with exact mode, fewer blocks than ranks.
    for (const std::string& bad : {std::string("--blocks 0"), std::string("--blocks 4 --distributed exact")}) {
      const CliRun r = testing::runCommand(testing::cliPath() + " " + common + " " + bad + " -o " + (dir / "bad").string() + " 2>&1");
      INFO(bad << ": " << r.out << r.err);
      CHECK(r.status == 1);
      CHECK((r.out + r.err).find("--blocks") != std::string::npos);
      CHECK(!fs::exists(dir / "bad"));
    }
    const CliRun few = testing::runCommand(mpirunPrefix() + "-np 4 " + testing::cliPath() + " " + common + " --blocks 2 -o " +
                                           (dir / "few").string() + " 2>&1");
    INFO(few.out << few.err);
    CHECK(few.status != 0);
    CHECK((few.out + few.err).find("2 blocks for 4 ranks") != std::string::npos);
    CHECK(!fs::exists(dir / "few" / "report.json"));
  }

  TEST_CASE("mpirun duplexfit fit: a bad input stops every rank with a clear error and writes nothing") {
    DUPLEXFIT_REQUIRE_MPIRUN();
    const fs::path dir = testing::scratchDir("mpi", "bad");
    const fs::path input = dir / "truncated.ply";
    testing::writeFile(input, "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\nproperty float y\n"
                              "property float z\nproperty float nx\nproperty float ny\nproperty float nz\nend_header\n" +
                                  std::string(24 * 100, '\0'));
    const CliRun r = testing::runCommand(mpirunPrefix() + "-np 2 " + testing::cliPath() + " fit " + input.string() +
                                         " --offset 0.05 --quiet -o " + (dir / "out").string() + " 2>&1");
    INFO(r.out << r.err);
    CHECK(r.status != 0);
    const std::string said = r.out + r.err;
    CHECK(said.find("truncated.ply: truncated binary body") != std::string::npos);
    CHECK(said.find("stopping every rank") != std::string::npos);
    CHECK(!fs::exists(dir / "out" / "report.json"));
  }
}
