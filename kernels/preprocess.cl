/* Point-cloud pre-processing kernels (bilateral filter, normal estimation). Program "preprocess".
 * One work-item per point; the launch is rounded up to the work-group size, so every kernel checks
 * its index against n. Positions are centred on the host (small coordinates keep float accurate), and
 * every kernel works with differences of nearby points only. Their C++ twins are in
 * lib/preprocess/preprocess_ref.hpp and must stay in step with these loops. */

/* Bilateral point filter (docs/method.md §9), one pass, all points at once.
 *   pos, nrm   3 REAL per point (xyz), the current positions and the unit (or zero) normals
 *   area       s_q = σ²/N(q) per point
 *   offsets    n + 1 CSR offsets into nbr; nbr holds the neighbours of point i (itself included)
 *   a          1/(2σ_ψ²)   (spatial weight ψ = exp(−a‖q − p‖²))
 *   b          1/σ_ζ² or 1/(2σ_ζ²)   (range weight ζ = exp(−b t²), t = (p − q)·n_q = ‖K_q(p) − p‖)
 *   disp       3 REAL per point: p' − p = Σ w (K_q(p) − p) / Σ w, with K_q(p) − p = −t n_q */
__kernel void bilateral_filter(const uint n, __global const real* pos, __global const real* nrm,
                               __global const real* area, __global const uint* offsets,
                               __global const uint* nbr, const real a, const real b,
                               __global real* disp) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  const real px = pos[3 * i], py = pos[3 * i + 1], pz = pos[3 * i + 2];
  real sw = 0, ax = 0, ay = 0, az = 0;
  const uint end = offsets[i + 1];
  for (uint e = offsets[i]; e < end; ++e) {
    const uint j = nbr[e];
    const real dx = px - pos[3 * j], dy = py - pos[3 * j + 1], dz = pz - pos[3 * j + 2];
    const real nx = nrm[3 * j], ny = nrm[3 * j + 1], nz = nrm[3 * j + 2];
    const real t = dx * nx + dy * ny + dz * nz;
    const real w = area[j] * exp(-(a * (dx * dx + dy * dy + dz * dz) + b * t * t));
    sw += w;
    ax -= w * t * nx;
    ay -= w * t * ny;
    az -= w * t * nz;
  }
  const real inv = sw > (real)0 ? (real)1 / sw : (real)0;
  disp[3 * i] = ax * inv;
  disp[3 * i + 1] = ay * inv;
  disp[3 * i + 2] = az * inv;
}

/* Covariance of each point's neighbourhood for PCA normals.
 *   k1     points per neighbourhood (the point and its k nearest neighbours), fixed stride of nbr
 *   nbr    n·k1 indices; the neighbourhood of i is nbr[i·k1 .. (i+1)·k1)
 *   cov    6 REAL per point: xx, xy, xz, yy, yz, zz of (1/k1) Σ (d − μ)(d − μ)ᵀ, d = q − p_i */
__kernel void pca_covariance(const uint n, const uint k1, __global const real* pos,
                             __global const uint* nbr, __global real* cov) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  const real px = pos[3 * i], py = pos[3 * i + 1], pz = pos[3 * i + 2];
  real mx = 0, my = 0, mz = 0;
  const ulong base = (ulong)i * k1;
  for (uint e = 0; e < k1; ++e) {
    const uint j = nbr[base + e];
    mx += pos[3 * j] - px;
    my += pos[3 * j + 1] - py;
    mz += pos[3 * j + 2] - pz;
  }
  const real inv = (real)1 / (real)k1;
  mx *= inv;
  my *= inv;
  mz *= inv;
  real xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
  for (uint e = 0; e < k1; ++e) {
    const uint j = nbr[base + e];
    const real dx = pos[3 * j] - px - mx, dy = pos[3 * j + 1] - py - my, dz = pos[3 * j + 2] - pz - mz;
    xx += dx * dx;
    xy += dx * dy;
    xz += dx * dz;
    yy += dy * dy;
    yz += dy * dz;
    zz += dz * dz;
  }
  __global real* c = cov + 6 * (ulong)i;
  c[0] = xx * inv;
  c[1] = xy * inv;
  c[2] = xz * inv;
  c[3] = yy * inv;
  c[4] = yz * inv;
  c[5] = zz * inv;
}
