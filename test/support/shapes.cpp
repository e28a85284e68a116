// Deterministic test data: Fibonacci-lattice sphere and torus samples, the three centre sets of a
// duplex-fit level (docs/method.md §3), a support radius for a requested row density, and random
// sparse SPD matrices from fixed seeds.
#include "shapes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "duplexfit/error.hpp"
#include "duplexfit/neighbors.hpp"

namespace duplexfit::testing {

namespace {

constexpr double kPi = 3.14159265358979323846;
/// 2π/φ², the golden angle, and 1/φ (φ the golden ratio).
constexpr double kGoldenAngle = 2.39996322972865332;
constexpr double kInverseGolden = 0.61803398874989484820;

constexpr double kSphereRadius = 0.5;
constexpr double kTorusMajor = 0.3;
constexpr double kTorusMinor = 0.15;

void checkCount(int n, const char* function) {
  if (n < 0) {
    throw InvalidArgument(std::string(function) + ": n must be non-negative, got " +
                          std::to_string(n));
  }
}

/// Surface points and outward normals of a shape with n samples.
Points surface(Shape shape, int n, Points& normals) {
  return shape == Shape::Sphere ? fibonacciSphere(n, kSphereRadius, &normals)
                                : sampledTorus(n, kTorusMajor, kTorusMinor, &normals);
}

double surfaceArea(Shape shape) {
  return shape == Shape::Sphere ? 4.0 * kPi * kSphereRadius * kSphereRadius
                                : 4.0 * kPi * kPi * kTorusMajor * kTorusMinor;
}

/// Signed offsets along the outward normal of the three centre kinds (surface, offset,
/// off-surface).
std::array<double, 3> layerOffsets(double delta, double sigma) {
  return {0.0, -delta, sigma / 10.0};
}

/// Mean non-zeros per row of a locally flat sheet sampling: each centre sees a disc of radius
/// √(σ² − h²) in every layer at normal separation h, holding (n / area)·π(σ² − h²) points.
double flatMeanNonZeros(double density, double delta, double sigma) {
  const auto offsets = layerOffsets(delta, sigma);
  double sum = 0.0;
  for (double a : offsets) {
    for (double b : offsets) {
      const double h = a - b;
      sum += std::max(0.0, sigma * sigma - h * h);
    }
  }
  return density * kPi * sum / 3.0;
}

/// For sampled rows of levelCentres(shape, n, delta, σ), the support radius at which each (row,
/// column) pair enters the matrix. A pair of centres p + a·n_p and q + b·n_q (a, b ∈ {0, −δ, σ/10})
/// is a non-zero iff ‖v + σw‖ < σ, with v, w independent of σ and ‖w‖ ≤ 0.2: that holds exactly for
/// σ above one threshold, so the mean row count at σ is the number of thresholds below σ per
/// sampled row.
class PairThresholds {
 public:
  PairThresholds(Shape shape, int n, double delta) : delta_(delta) {
    points_ = surface(shape, n, normals_);
    const int s = std::min(n, 300);
    queries_.resize(s, 3);
    for (int i = 0; i < s; ++i) {
      const int row = static_cast<int>((std::int64_t{2 * i + 1} * n) / (2 * s));
      rows_.push_back(row);
      queries_.row(i) = points_.row(row);
    }
    index_ = std::make_unique<NeighborIndex>(points_);
  }

  std::size_t sampledRows() const { return 3 * rows_.size(); }

  /// The sorted thresholds below maxSigma of the sampled rows' pairs, or of all of them when the
  /// candidate search reached every point (*complete is then set).
  std::vector<double> thresholds(double maxSigma, bool* complete) const {
    // Candidates: surface points that can come within maxSigma once both moved along their normals.
    const double reach = maxSigma + 2.0 * std::max(std::abs(delta_), maxSigma / 10.0);
    const NeighborLists lists = index_->radiusSearch(queries_, reach * (1.0 + 1e-9));
    *complete = lists.indices.size() == rows_.size() * static_cast<std::size_t>(points_.rows());
    // Layer kinds: 0 surface (offset 0), 1 offset (−δ), 2 off-surface (σ/10, so it enters w).
    const double fixedOffset[3] = {0.0, -delta_, 0.0};
    const double sigmaFactor[3] = {0.0, 0.0, 0.1};
    std::vector<double> out;
    for (std::size_t s = 0; s < rows_.size(); ++s) {
      const double* p = points_.data() + 3 * static_cast<std::size_t>(rows_[s]);
      const double* np = normals_.data() + 3 * static_cast<std::size_t>(rows_[s]);
      for (auto k = lists.offsets[s]; k < lists.offsets[s + 1]; ++k) {
        const auto j = static_cast<std::size_t>(lists.indices[static_cast<std::size_t>(k)]);
        const double* q = points_.data() + 3 * j;
        const double* nq = normals_.data() + 3 * j;
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) {
            double vv = 0.0;
            double vw = 0.0;
            double ww = 0.0;
            for (int c = 0; c < 3; ++c) {
              const double v = q[c] + fixedOffset[b] * nq[c] - p[c] - fixedOffset[a] * np[c];
              const double w = sigmaFactor[b] * nq[c] - sigmaFactor[a] * np[c];
              vv += v * v;
              vw += v * w;
              ww += w * w;
            }
            // ‖v + σw‖² < σ²  ⇔  (1 − ww)σ² − 2·vw·σ − vv > 0  ⇔  σ > the larger root.
            const double t = (vw + std::sqrt(vw * vw + (1.0 - ww) * vv)) / (1.0 - ww);
            if (t < maxSigma || *complete) out.push_back(t);
          }
        }
      }
    }
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  double delta_;
  Points points_;
  Points normals_;
  Points queries_;
  std::vector<int> rows_;
  std::unique_ptr<NeighborIndex> index_;
};

}  // namespace

Points fibonacciSphere(int n, double radius, Points* normals) {
  checkCount(n, "fibonacciSphere");
  Points p(n, 3);
  Points nn(n, 3);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double rho = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = kGoldenAngle * i;
    nn.row(i) << rho * std::cos(phi), rho * std::sin(phi), z;
    nn.row(i).normalize();
    p.row(i) = radius * nn.row(i);
  }
  if (normals != nullptr) *normals = std::move(nn);
  return p;
}

Points torusGrid(double majorRadius, double rho, int n) {
  Points p(n * n, 3);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double u = 2 * M_PI * (i + 0.5) / n, v = 2 * M_PI * (j + 0.37) / n;
      p.row(i * n + j) << (majorRadius + rho * std::cos(v)) * std::cos(u), (majorRadius + rho * std::cos(v)) * std::sin(u),
          rho * std::sin(v);
    }
  }
  return p;
}

Points sampledTorus(int n, double majorRadius, double minorRadius, Points* normals) {
  checkCount(n, "sampledTorus");
  if (!(minorRadius > 0.0) || !(majorRadius > minorRadius)) {
    throw InvalidArgument("sampledTorus: need 0 < minorRadius < majorRadius");
  }
  // A 2D Fibonacci lattice in (t, u) mapped to the tube angle v through the inverse of the area CDF
  // F(v) = (R v + r sin v) / (2πR) (area element ∝ R + r cos v), so the samples are area-uniform.
  Points p(n, 3);
  Points nn(n, 3);
  const double twoPiR = 2.0 * kPi * majorRadius;
  for (int i = 0; i < n; ++i) {
    const double t = (i + 0.5) / n;
    double v = 2.0 * kPi * t;
    for (int it = 0; it < 50; ++it) {
      const double f = majorRadius * v + minorRadius * std::sin(v) - twoPiR * t;
      const double step = f / (majorRadius + minorRadius * std::cos(v));
      v -= step;
      if (std::abs(step) < 1e-15) break;
    }
    const double frac = i * kInverseGolden - std::floor(i * kInverseGolden);
    const double u = 2.0 * kPi * frac;
    const double ring = majorRadius + minorRadius * std::cos(v);
    p.row(i) << ring * std::cos(u), ring * std::sin(u), minorRadius * std::sin(v);
    nn.row(i) << std::cos(v) * std::cos(u), std::cos(v) * std::sin(u), std::sin(v);
  }
  if (normals != nullptr) *normals = std::move(nn);
  return p;
}

LevelCentres levelCentres(Shape shape, int n, double delta, double sigma) {
  checkCount(n, "levelCentres");
  Points normals;
  const Points s = surface(shape, n, normals);
  LevelCentres level;
  level.centres.resize(3 * static_cast<Eigen::Index>(n), 3);
  level.centres.topRows(n) = s;
  level.centres.middleRows(n, n) = s - delta * normals;
  level.centres.bottomRows(n) = s + (sigma / 10.0) * normals;
  level.surface = n;
  level.offset = n;
  level.offSurface = n;
  level.sigma = sigma;
  return level;
}

double sigmaForNonZeros(Shape shape, int n, double delta, double nnzPerRow) {
  if (n <= 0 || !(nnzPerRow >= 1.0)) {
    throw InvalidArgument("sigmaForNonZeros: need n > 0 and nnzPerRow >= 1");
  }
  // First guess from the flat-sheet model, solved by bisection (the count grows with σ).
  const double density = n / surfaceArea(shape);
  double lo = 0.0;
  double hi = 1.0;
  while (flatMeanNonZeros(density, delta, hi) < nnzPerRow && hi < 1e6) hi *= 2.0;
  for (int it = 0; it < 100; ++it) {
    const double mid = 0.5 * (lo + hi);
    (flatMeanNonZeros(density, delta, mid) < nnzPerRow ? lo : hi) = mid;
  }
  const double guess = hi;

  // Refine against the exact entry thresholds of sampled rows (the sheet model ignores curvature):
  // the wanted σ lies between the k-th and (k+1)-th smallest threshold, k = nnzPerRow × rows.
  const PairThresholds pairs(shape, n, delta);
  const auto k =
      static_cast<std::size_t>(std::llround(nnzPerRow * static_cast<double>(pairs.sampledRows())));
  double maxSigma = 2.0 * guess;
  for (;;) {
    bool complete = false;
    const std::vector<double> t = pairs.thresholds(maxSigma, &complete);
    if (t.size() > k) return 0.5 * (t[k - 1] + t[k]);
    if (complete) return 1.01 * t.back();  // more than every centre was asked for
    maxSigma *= 2.0;
  }
}

CsrMatrix randomSpdMatrix(int n, int nnzPerRow, std::uint32_t seed) {
  checkCount(n, "randomSpdMatrix");
  CsrMatrix a;
  a.rows = n;
  a.cols = n;
  a.rowPtr.assign(static_cast<std::size_t>(n) + 1, 0);
  if (n == 0) return a;

  // Off-diagonal pairs (i, j, v) and (j, i, v): row i draws (nnzPerRow − 1)/2 partners, so a row
  // ends up with about nnzPerRow entries with the ones drawn by other rows.
  const int draws = n > 1 ? std::max(0, (nnzPerRow - 1) / 2) : 0;
  std::mt19937 engine(seed);
  std::uniform_int_distribution<int> partner(0, std::max(0, n - 2));
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  struct Triplet {
    Index row;
    Index col;
    double value;
  };
  std::vector<Triplet> pairs;
  pairs.reserve(2 * static_cast<std::size_t>(n) * static_cast<std::size_t>(draws));
  for (int i = 0; i < n; ++i) {
    for (int d = 0; d < draws; ++d) {
      int j = partner(engine);
      if (j >= i) ++j;  // skip the diagonal
      const double v = value(engine);
      pairs.push_back({i, j, v});
      pairs.push_back({j, i, v});
    }
  }

  // Counting sort by row (stable), then a stable sort by column inside each row; duplicates are
  // summed in generation order, which is the same for (i, j) and (j, i), so the matrix is exactly
  // symmetric.
  std::vector<std::size_t> start(static_cast<std::size_t>(n) + 1, 0);
  for (const Triplet& t : pairs) ++start[static_cast<std::size_t>(t.row) + 1];
  for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  std::vector<Triplet> byRow(pairs.size());
  {
    std::vector<std::size_t> next(start.begin(), start.end() - 1);
    for (const Triplet& t : pairs) byRow[next[static_cast<std::size_t>(t.row)]++] = t;
  }
  std::vector<Triplet>().swap(pairs);

  a.colIdx.reserve(byRow.size() + static_cast<std::size_t>(n));
  a.values.reserve(byRow.size() + static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto first =
        byRow.begin() + static_cast<std::ptrdiff_t>(start[static_cast<std::size_t>(i)]);
    const auto last =
        byRow.begin() + static_cast<std::ptrdiff_t>(start[static_cast<std::size_t>(i) + 1]);
    std::stable_sort(first, last, [](const Triplet& x, const Triplet& y) { return x.col < y.col; });
    double absSum = 0.0;
    bool diagonalPlaced = false;
    std::size_t diagonalAt = 0;
    for (auto it = first; it != last;) {
      const Index col = it->col;
      double v = 0.0;
      for (; it != last && it->col == col; ++it) v += it->value;
      if (!diagonalPlaced && col > i) {
        diagonalAt = a.values.size();
        a.colIdx.push_back(i);
        a.values.push_back(0.0);
        diagonalPlaced = true;
      }
      a.colIdx.push_back(col);
      a.values.push_back(v);
      absSum += std::abs(v);
    }
    if (!diagonalPlaced) {
      diagonalAt = a.values.size();
      a.colIdx.push_back(i);
      a.values.push_back(0.0);
    }
    // Strict diagonal dominance with margin 1: every Gershgorin disc lies in [1, ∞).
    a.values[diagonalAt] = absSum + 1.0;
    a.rowPtr[static_cast<std::size_t>(i) + 1] = static_cast<Index>(a.values.size());
  }
  return a;
}

}  // namespace duplexfit::testing
