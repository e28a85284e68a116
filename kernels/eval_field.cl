/* Evaluation of the multi-level CSRBF field (docs/method.md section 6) at query points (needs common.cl):
 *   f(x) = f0 + sum_levels sum_{|x - c_j| < sigma} w_j phi(|x - c_j| / sigma),  phi(r) = (1-r)^4 (4r+1)
 * with optional gradient and Hessian. One work-item per query. Each level's centres are bucketed in a
 * uniform grid whose cells are at least sigma wide, so only the 27 cells around the query's cell can
 * hold centres within the support.
 * Arguments:
 *   nq, queries[3*nq]           query points (normalised coordinates)
 *   nlevels                     how many levels (from the first) to sum
 *   params[6*L]                 per level: origin x, y, z, 1/cell, sigma, 1/sigma
 *   dims[5*L]                   per level: nx, ny, nz, offset into cell_start, offset into centres
 *   cell_start[]                per level nx*ny*nz+1 prefix offsets (relative to the level's centres)
 *   centres[4*N]                x, y, z, weight of every centre, sorted by cell within each level
 *   f0                          the constant base field
 *   out[K*nq]                   K = 1 (f), 4 (f, df/dx, df/dy, df/dz) or 10 (f, gradient, Hessian
 *                               xx, xy, xz, yy, yz, zz), query-major */

inline void eval_point(const uint q, __global const real* queries, const uint nlevels,
                       __global const real* params, __global const uint* dims,
                       __global const uint* cell_start, __global const real* centres,
                       const real f0, __global real* out, const int k) {
  const real x = queries[3 * q], y = queries[3 * q + 1], z = queries[3 * q + 2];
  real f = f0;
  real gx = 0, gy = 0, gz = 0;
  real hxx = 0, hxy = 0, hxz = 0, hyy = 0, hyz = 0, hzz = 0;
  for (uint l = 0; l < nlevels; ++l) {
    const real ox = params[6 * l], oy = params[6 * l + 1], oz = params[6 * l + 2];
    const real inv_cell = params[6 * l + 3], sigma = params[6 * l + 4], inv_sigma = params[6 * l + 5];
    const int nx = (int)dims[5 * l], ny = (int)dims[5 * l + 1], nz = (int)dims[5 * l + 2];
    const uint cs_off = dims[5 * l + 3], c_off = dims[5 * l + 4];
    const int cx = (int)floor((x - ox) * inv_cell);
    const int cy = (int)floor((y - oy) * inv_cell);
    const int cz = (int)floor((z - oz) * inv_cell);
    if (cx < -1 || cy < -1 || cz < -1 || cx > nx || cy > ny || cz > nz) continue;
    const real s2 = sigma * sigma;
    const real h_scale = (real)20 * inv_sigma * inv_sigma;
    for (int iz = max(cz - 1, 0); iz <= min(cz + 1, nz - 1); ++iz) {
      for (int iy = max(cy - 1, 0); iy <= min(cy + 1, ny - 1); ++iy) {
        const uint row = cs_off + (uint)((iz * ny + iy) * nx);
        const int x0 = max(cx - 1, 0), x1 = min(cx + 1, nx - 1);
        if (x0 > x1) continue;
        /* cells x0..x1 of one row are contiguous in the sorted centres */
        const uint b = cell_start[row + (uint)x0] + c_off;
        const uint e = cell_start[row + (uint)x1 + 1] + c_off;
        for (uint j = b; j < e; ++j) {
          const real ux = x - centres[4 * j], uy = y - centres[4 * j + 1], uz = z - centres[4 * j + 2];
          const real d2 = ux * ux + uy * uy + uz * uz;
          if (d2 >= s2) continue;
          const real w = centres[4 * j + 3];
          const real rho = sqrt(d2);
          const real r = rho * inv_sigma;
          const real t = (real)1 - r;
          const real t2 = t * t;
          f += w * t2 * t2 * ((real)4 * r + (real)1);
          if (k >= 4) {
            const real g = -w * h_scale * t2 * t;
            gx += g * ux;
            gy += g * uy;
            gz += g * uz;
          }
          if (k >= 10) {
            /* H = w 20/sigma^2 (1-r)^2 [3 r u u^T / rho^2 - (1-r) I]; the first term vanishes at rho=0 */
            const real a = w * h_scale * t2;
            const real c = rho > (real)0 ? (real)3 * r / d2 : (real)0;
            hxx += a * (c * ux * ux - t);
            hyy += a * (c * uy * uy - t);
            hzz += a * (c * uz * uz - t);
            hxy += a * c * ux * uy;
            hxz += a * c * ux * uz;
            hyz += a * c * uy * uz;
          }
        }
      }
    }
  }
  out[(ulong)k * q] = f;
  if (k >= 4) {
    out[(ulong)k * q + 1] = gx;
    out[(ulong)k * q + 2] = gy;
    out[(ulong)k * q + 3] = gz;
  }
  if (k >= 10) {
    out[(ulong)k * q + 4] = hxx;
    out[(ulong)k * q + 5] = hxy;
    out[(ulong)k * q + 6] = hxz;
    out[(ulong)k * q + 7] = hyy;
    out[(ulong)k * q + 8] = hyz;
    out[(ulong)k * q + 9] = hzz;
  }
}

__kernel void eval_field_value(const uint nq, __global const real* queries, const uint nlevels,
                               __global const real* params, __global const uint* dims,
                               __global const uint* cell_start, __global const real* centres,
                               const real f0, __global real* out) {
  const uint q = get_global_id(0);
  if (q < nq) eval_point(q, queries, nlevels, params, dims, cell_start, centres, f0, out, 1);
}

__kernel void eval_field_gradient(const uint nq, __global const real* queries, const uint nlevels,
                                  __global const real* params, __global const uint* dims,
                                  __global const uint* cell_start, __global const real* centres,
                                  const real f0, __global real* out) {
  const uint q = get_global_id(0);
  if (q < nq) eval_point(q, queries, nlevels, params, dims, cell_start, centres, f0, out, 4);
}

__kernel void eval_field_hessian(const uint nq, __global const real* queries, const uint nlevels,
                                 __global const real* params, __global const uint* dims,
                                 __global const uint* cell_start, __global const real* centres,
                                 const real f0, __global real* out) {
  const uint q = get_global_id(0);
  if (q < nq) eval_point(q, queries, nlevels, params, dims, cell_start, centres, f0, out, 10);
}
