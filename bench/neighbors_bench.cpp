// duplexfit-neighbors-bench CLOUD [--step S ...] [--queries N] [--slab X0,X1] [--repeat N]: the companions'
// validity search (docs/method.md §3.1) both ways: for queries q = p − S·n (S into the solid) the nearest
// cloud point other than p, from the k-d tree (two nearest, NeighborIndex) and from the tight-box BVH
// (detail::PointBvh), on every thread. Prints the median nearest-neighbour spacing, and per step the
// spacings it spans, µs per query of each (minimum of N runs) and whether the two answers are identical.
// `--slab` keeps the points with X0 ≤ x < X1 (a block of a big cloud at its full density).
// docs/benchmarks.md ("Nearest other point") keeps the figures; fit/constraints.cpp picks by them.
#include <algorithm>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "duplexfit/error.hpp"
#include "duplexfit/io.hpp"
#include "duplexfit/neighbors.hpp"
#include "duplexfit/timer.hpp"
#include "spatial/point_bvh.hpp"

using duplexfit::Points;

int main(int argc, char** argv) {
  CLI::App app{"duplexfit-neighbors-bench: nearest other point from the k-d tree and from the BVH"};
  std::string path;
  std::vector<double> steps{0.025};
  std::vector<double> slab;
  long long queries = 200000;
  int repeat = 2;
  app.add_option("CLOUD", path, "an oriented point cloud (PLY or XYZ)")->required();
  app.add_option("--step", steps, "distances of the queries from their points, comma-separated (default 0.025)")->delimiter(',');
  app.add_option("--queries", queries, "evenly strided queries (0: one per point)")->check(CLI::NonNegativeNumber);
  app.add_option("--slab", slab, "X0,X1: keep the points with X0 <= x < X1")->expected(2)->delimiter(',');
  app.add_option("--repeat", repeat, "runs of each search; the minimum is printed")->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  try {
    const duplexfit::PointSet cloud = duplexfit::readPointCloud(path);
    Points p = cloud.positions(), n = cloud.normals();
    if (slab.size() == 2) {
      Eigen::Index kept = 0;
      for (Eigen::Index i = 0; i < p.rows(); ++i) {
        if (p(i, 0) >= slab[0] && p(i, 0) < slab[1]) {
          p.row(kept) = p.row(i);
          n.row(kept) = n.row(i);
          ++kept;
        }
      }
      p.conservativeResize(kept, 3);
      n.conservativeResize(kept, 3);
    }
    const Eigen::Index count = queries > 0 ? std::min<Eigen::Index>(static_cast<Eigen::Index>(queries), p.rows()) : p.rows();
    if (count < 2) throw duplexfit::InvalidArgument(path + ": fewer than 2 points to search");
    std::vector<Eigen::Index> src(static_cast<std::size_t>(count));
    for (Eigen::Index s = 0; s < count; ++s) src[static_cast<std::size_t>(s)] = s * p.rows() / count;

    duplexfit::Timer build;
    const duplexfit::NeighborIndex tree(p);
    const double treeBuild = build.seconds();
    build.restart();
    const duplexfit::detail::PointBvh bvh(p);
    const double bvhBuild = build.seconds();
    // The median spacing, as fit/constraints.cpp measures it: nearest other point of 1,024 strided points.
    std::vector<Eigen::Index> sampleSrc;
    for (Eigen::Index s = 0; s < 1024 && s < p.rows(); ++s) sampleSrc.push_back(s * p.rows() / std::min<Eigen::Index>(1024, p.rows()));
    Points sample(static_cast<Eigen::Index>(sampleSrc.size()), 3);
    for (std::size_t s = 0; s < sampleSrc.size(); ++s) sample.row(static_cast<Eigen::Index>(s)) = p.row(sampleSrc[s]);
    std::vector<double> sd;
    std::vector<Eigen::Index> so;
    bvh.nearestOther(sample, sampleSrc, sd, so);
    std::nth_element(sd.begin(), sd.begin() + static_cast<std::ptrdiff_t>(sd.size() / 2), sd.end());
    const double spacing = sd[sd.size() / 2];
    std::cout << p.rows() << " points, median spacing " << spacing << ", build: tree " << treeBuild << " s, BVH "
              << bvhBuild << " s; " << count << " queries\n";
    std::cout << "step  spacings  tree us/query  BVH us/query  identical\n";
    for (const double step : steps) {
      Points q(count, 3);
      for (Eigen::Index s = 0; s < count; ++s) q.row(s) = p.row(src[static_cast<std::size_t>(s)]) - step * n.row(src[static_cast<std::size_t>(s)]);
      std::vector<double> dt, db;
      std::vector<Eigen::Index> ot, ob;
      double bestTree = std::numeric_limits<double>::infinity(), bestBvh = bestTree;
      for (int r = 0; r < repeat; ++r) {
        duplexfit::Timer t;
        duplexfit::detail::nearestOtherInTree(tree, q, src, dt, ot);
        bestTree = std::min(bestTree, t.seconds());
        t.restart();
        bvh.nearestOther(q, src, db, ob);
        bestBvh = std::min(bestBvh, t.seconds());
      }
      const bool same = dt == db && ot == ob;
      std::cout << step << "  " << step / spacing << "  " << 1e6 * bestTree / static_cast<double>(count) << "  "
                << 1e6 * bestBvh / static_cast<double>(count) << "  " << (same ? "yes" : "NO") << "\n";
      if (!same) return 1;
    }
  } catch (const std::exception& e) {
    std::cerr << "duplexfit-neighbors-bench: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
