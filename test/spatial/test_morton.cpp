// mortonSortedKeys (spatial/morton.hpp: the order of every tree build and batched search) against its
// definition: the entries stably sorted by the Morton code of their point in a 1024³ grid fitted to the
// points' box, as keys code << 32 | entry; below and above the size where it runs on the team's threads,
// with repeated points and codes.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "spatial/morton.hpp"

namespace {

std::vector<std::uint64_t> byDefinition(const duplexfit::Points& p) {
  double lo[3], hi[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = p.col(a).minCoeff();
    hi[a] = p.col(a).maxCoeff();
  }
  const duplexfit::detail::MortonGrid grid(lo, hi, duplexfit::detail::MortonGrid::Box::Fitted, 10);
  std::vector<std::uint64_t> key(static_cast<std::size_t>(p.rows()));
  for (Eigen::Index i = 0; i < p.rows(); ++i) key[static_cast<std::size_t>(i)] = (grid.key(p, i) << 32) | static_cast<std::uint64_t>(i);
  std::stable_sort(key.begin(), key.end(), [](std::uint64_t a, std::uint64_t b) { return (a >> 32) < (b >> 32); });
  return key;
}

}  // namespace

TEST_SUITE("spatial") {
TEST_CASE("morton: sorted keys are the stable sort by code, on one thread and on the team") {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 3.0);
  for (const Eigen::Index n : {Eigen::Index{1}, Eigen::Index{1000}, Eigen::Index{65535}, Eigen::Index{65536},
                               Eigen::Index{300001}}) {
    CAPTURE(n);
    duplexfit::Points p(n, 3);
    for (Eigen::Index i = 0; i < n; ++i) {
      // A third of the points repeat an earlier one (equal codes: the entry order decides).
      if (i > 0 && i % 3 == 0) {
        p.row(i) = p.row(static_cast<Eigen::Index>(rng() % static_cast<std::uint64_t>(i)));
      } else {
        p.row(i) << u(rng), u(rng), 0.01 * u(rng);
      }
    }
    const std::vector<std::uint64_t> got = duplexfit::detail::mortonSortedKeys(
        static_cast<std::size_t>(n), [&p](std::size_t i, double* x) {
          for (int a = 0; a < 3; ++a) x[a] = p(static_cast<Eigen::Index>(i), a);
        });
    CHECK(got == byDefinition(p));
  }
}
}
