// Reference twins of kernels/preprocess.cl: the same loops in plain C++ (OpenMP), used on the reference
// device and by the tests as the oracle for the OpenCL kernels. Keep them in step with the kernels.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace duplexfit::detail {

/// Twin of bilateral_filter: displacement p' − p of each of the n points (3 T each).
template <typename T>
void bilateralFilterReference(std::size_t n, const T* pos, const T* nrm, const T* area, const std::uint32_t* offsets,
                              const std::uint32_t* nbr, T a, T b, T* disp) {
#pragma omp parallel for schedule(dynamic, 1024)
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(n); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const T px = pos[3 * i], py = pos[3 * i + 1], pz = pos[3 * i + 2];
    T sw = 0, ax = 0, ay = 0, az = 0;
    for (std::uint32_t e = offsets[i]; e < offsets[i + 1]; ++e) {
      const std::size_t j = nbr[e];
      const T dx = px - pos[3 * j], dy = py - pos[3 * j + 1], dz = pz - pos[3 * j + 2];
      const T nx = nrm[3 * j], ny = nrm[3 * j + 1], nz = nrm[3 * j + 2];
      const T t = dx * nx + dy * ny + dz * nz;
      const T w = area[j] * std::exp(-(a * (dx * dx + dy * dy + dz * dz) + b * t * t));
      sw += w;
      ax -= w * t * nx;
      ay -= w * t * ny;
      az -= w * t * nz;
    }
    const T inv = sw > T(0) ? T(1) / sw : T(0);
    disp[3 * i] = ax * inv;
    disp[3 * i + 1] = ay * inv;
    disp[3 * i + 2] = az * inv;
  }
}

/// Twin of pca_covariance: 6 T per point (xx, xy, xz, yy, yz, zz) of the k1-point neighbourhood.
template <typename T>
void pcaCovarianceReference(std::size_t n, std::size_t k1, const T* pos, const std::uint32_t* nbr, T* cov) {
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t ii = 0; ii < static_cast<std::ptrdiff_t>(n); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const T px = pos[3 * i], py = pos[3 * i + 1], pz = pos[3 * i + 2];
    const std::uint32_t* nb = nbr + i * k1;
    T mx = 0, my = 0, mz = 0;
    for (std::size_t e = 0; e < k1; ++e) {
      const std::size_t j = nb[e];
      mx += pos[3 * j] - px;
      my += pos[3 * j + 1] - py;
      mz += pos[3 * j + 2] - pz;
    }
    const T inv = T(1) / static_cast<T>(k1);
    mx *= inv;
    my *= inv;
    mz *= inv;
    T xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
    for (std::size_t e = 0; e < k1; ++e) {
      const std::size_t j = nb[e];
      const T dx = pos[3 * j] - px - mx, dy = pos[3 * j + 1] - py - my, dz = pos[3 * j + 2] - pz - mz;
      xx += dx * dx;
      xy += dx * dy;
      xz += dx * dz;
      yy += dy * dy;
      yz += dy * dz;
      zz += dz * dz;
    }
    T* c = cov + 6 * i;
    c[0] = xx * inv;
    c[1] = xy * inv;
    c[2] = xz * inv;
    c[3] = yy * inv;
    c[4] = yz * inv;
    c[5] = zz * inv;
  }
}

}  // namespace duplexfit::detail
