// Helpers of the preprocess tests: noisy analytic spheres, angles between normal fields, and a mask of the
// points away from sharp edges.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "duplexfit/neighbors.hpp"
#include "duplexfit/point_set.hpp"
#include "shapes.hpp"

namespace duplexfit::testing {

/// n Fibonacci points on a sphere (centre, radius) with exact outward normals, positions perturbed by
/// Gaussian noise of standard deviation `noise` per coordinate (fixed seed).
inline PointSet noisySphere(int n, double radius, double noise, const Eigen::RowVector3d& centre = {0, 0, 0},
                            std::uint32_t seed = 7) {
  Points normals;
  Points p = fibonacciSphere(n, radius, &normals);
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    for (int c = 0; c < 3; ++c) p(i, c) += noise * g(rng);
  }
  p.rowwise() += centre;
  return PointSet(p, normals);
}

/// RMS and mean of ‖p − c‖ − r over the points.
struct RadialError {
  double rms = 0.0;
  double mean = 0.0;
};
inline RadialError radialError(const Points& p, double radius, const Eigen::RowVector3d& centre = {0, 0, 0}) {
  RadialError e;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    const double d = (p.row(i) - centre).norm() - radius;
    e.rms += d * d;
    e.mean += d;
  }
  e.rms = std::sqrt(e.rms / static_cast<double>(p.rows()));
  e.mean /= static_cast<double>(p.rows());
  return e;
}

/// Angle in degrees between two unit vectors (unsigned if `unsignedAngle`).
inline double angleDeg(const Eigen::RowVector3d& a, const Eigen::RowVector3d& b, bool unsignedAngle = false) {
  double c = a.dot(b);
  if (unsignedAngle) c = std::abs(c);
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / M_PI;
}

/// Points away from sharp edges: no true normal among its k nearest neighbours differs by more than
/// `maxDeg` degrees from its own.
inline std::vector<char> smoothMask(const PointSet& truth, int k = 15, double maxDeg = 20.0) {
  const NeighborIndex index(truth.positions());
  const NeighborLists l = index.knnSearch(truth.positions(), k + 1);
  const double cosMax = std::cos(maxDeg * M_PI / 180.0);
  std::vector<char> mask(truth.size(), 1);
  for (std::size_t i = 0; i < truth.size(); ++i) {
    for (auto e = l.offsets[i]; e < l.offsets[i + 1]; ++e) {
      const auto j = static_cast<Eigen::Index>(l.indices[static_cast<std::size_t>(e)]);
      if (truth.normals().row(static_cast<Eigen::Index>(i)).dot(truth.normals().row(j)) < cosMax) {
        mask[i] = 0;
        break;
      }
    }
  }
  return mask;
}

}  // namespace duplexfit::testing
