// The Wendland CSRBF φ(r) = (1 − r)⁴₊(4r + 1) (docs/method.md §2) with its first two derivatives (the
// host's scalar φ: the level matrix and the brute-force field oracle; the batched evaluation has its own
// body in kernels/field_point.cl), and the assembly of the level system Φ_ij = φ(‖c_i − c_j‖/σ) + λδ_ij
// as a CSR matrix.
#pragma once

#include "duplexfit/sparse.hpp"
#include "duplexfit/types.hpp"

namespace duplexfit {

/// φ(r) = (1 − r)⁴(4r + 1) for 0 ≤ r < 1, 0 for r ≥ 1.
inline double wendland(double r) noexcept {
  if (r >= 1.0) return 0.0;
  const double s = 1.0 - r;
  const double s2 = s * s;
  return s2 * s2 * (4.0 * r + 1.0);
}

/// φ'(r) = −20 r (1 − r)³ on [0, 1), 0 beyond.
inline double wendlandDerivative(double r) noexcept {
  if (r >= 1.0) return 0.0;
  const double s = 1.0 - r;
  return -20.0 * r * s * s * s;
}

/// φ''(r) = 20 (1 − r)² (4r − 1) on [0, 1), 0 beyond.
inline double wendlandSecondDerivative(double r) noexcept {
  if (r >= 1.0) return 0.0;
  const double s = 1.0 - r;
  return 20.0 * s * s * (4.0 * r - 1.0);
}

/// Assembles Φ + λI over the centres (#C×3) with support radius sigma: entry (i, j) is stored when
/// ‖c_i − c_j‖ < σ; columns sorted; the result is symmetric and, for distinct centres, SPD.
/// @throws InvalidArgument when sigma ≤ 0, lambda < 0, a value is not finite, or the matrix would
///         exceed 2^31 − 1 non-zeros.
CsrMatrix assembleWendland(const Points& centres, double sigma, double lambda = 0.0);

}  // namespace duplexfit
