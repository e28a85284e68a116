// Generated test data with fixed seeds: sampled shapes with the three kinds of centres of a duplex-fit
// level (surface, offset δ inward, off-surface σ/10 outward) and random SPD matrices.
#pragma once

#include <cstdint>

#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit::testing {

/// n points on a sphere of the given radius centred at the origin (Fibonacci lattice), with outward
/// unit normals written to *normals when it is not null.
Points fibonacciSphere(int n, double radius, Points* normals = nullptr);

/// n points on a torus (major radius R, minor radius r, axis z), roughly area-uniform, deterministic.
Points sampledTorus(int n, double majorRadius, double minorRadius, Points* normals = nullptr);

/// The n×n points of a regular (u, v) parameter grid on the torus with major radius R and tube radius rho
/// (axis z), v offset by 0.37 of a step: probes of a torus-shaped level set.
Points torusGrid(double majorRadius, double rho, int n);

/// Centres of one duplex-fit level: the surface points, then their copies δ along the inward normal,
/// then their copies σ/10 along the outward normal (3n rows in that order).
struct LevelCentres {
  Points centres;
  int surface = 0;
  int offset = 0;
  int offSurface = 0;
  double sigma = 0.0;
};

enum class Shape { Sphere, Torus };

/// The centres for a sampled sphere (radius 0.5) or torus (R = 0.3, r = 0.15) with n surface points,
/// inward offset delta and support sigma.
LevelCentres levelCentres(Shape shape, int n, double delta, double sigma);

/// A support radius for which Wendland rows of levelCentres(shape, n, delta, ·) hold about
/// nnzPerRow non-zeros on average.
double sigmaForNonZeros(Shape shape, int n, double delta, double nnzPerRow);

/// A random sparse symmetric strictly diagonally dominant (hence SPD) n×n matrix with about
/// nnzPerRow non-zeros a row, from a fixed seed.
CsrMatrix randomSpdMatrix(int n, int nnzPerRow, std::uint32_t seed);

}  // namespace duplexfit::testing
