/* The field at one point (docs/method.md section 6): the ONE body of the evaluation loop, compiled both
 * as OpenCL C (the "field" program: common.cl, this file, eval_field.cl) and as C++ (included by
 * lib/field/field_evaluator.cpp, the reference device's twin, where `real` is a template parameter).
 *   f(x) = f0 + sum_levels sum_{|x - c_j| < sigma} w_j phi(|x - c_j| / sigma),  phi(r) = (1-r)^4 (4r+1)
 *   grad f = sum -w 20/sigma^2 (1-r)^3 u                                     (u = x - c_j)
 *   H      = sum  w 20/sigma^2 (1-r)^2 [3 r u u^T / |u|^2 - (1-r) I]         (first term 0 at u = 0)
 * Each level's centres are bucketed in a uniform grid whose cells are at least sigma wide, so only the
 * 27 cells around the query's cell can hold centres within the support.
 *   params[6*L]   per level: origin x, y, z, 1/cell, sigma, 1/sigma
 *   dims[5*L]     per level: nx, ny, nz, offset into cell_start, offset into centres
 *   cell_start[]  per level nx*ny*nz+1 prefix offsets (relative to the level's centres)
 *   centres[4*N]  x, y, z, weight of every centre, sorted by cell within each level
 *   acc[k]        out: f (k = 1), then the gradient (k = 4), then Hessian xx, xy, xz, yy, yz, zz (k = 10)
 * The independent oracle is the brute-force sum in lib/field/field.cpp (ImplicitField::value etc.). */
#ifdef __OPENCL_VERSION__
#define DPX_FN inline
#define DPX_GLOBAL __global
#define DPX_UINT uint
#define DPX_FLOOR floor
#define DPX_SQRT sqrt
#define DPX_MIN min
#define DPX_MAX max
#define DPX_CAST(type, value) ((type)(value))
#else
#define DPX_FN template <typename real> inline
#define DPX_GLOBAL
#define DPX_UINT std::uint32_t
#define DPX_FLOOR std::floor
#define DPX_SQRT std::sqrt
#define DPX_MIN std::min
#define DPX_MAX std::max
#define DPX_CAST(type, value) static_cast<type>(value)
#endif

DPX_FN void dpx_field_point(const real x, const real y, const real z, const DPX_UINT nlevels,
                            DPX_GLOBAL const real* params, DPX_GLOBAL const DPX_UINT* dims,
                            DPX_GLOBAL const DPX_UINT* cell_start, DPX_GLOBAL const real* centres,
                            const real f0, const int k, real* acc) {
  real f = f0;
  real gx = 0, gy = 0, gz = 0;
  real hxx = 0, hxy = 0, hxz = 0, hyy = 0, hyz = 0, hzz = 0;
  for (DPX_UINT l = 0; l < nlevels; ++l) {
    const real ox = params[6 * l], oy = params[6 * l + 1], oz = params[6 * l + 2];
    const real inv_cell = params[6 * l + 3], sigma = params[6 * l + 4], inv_sigma = params[6 * l + 5];
    const int nx = DPX_CAST(int, dims[5 * l]), ny = DPX_CAST(int, dims[5 * l + 1]), nz = DPX_CAST(int, dims[5 * l + 2]);
    const DPX_UINT cs_off = dims[5 * l + 3], c_off = dims[5 * l + 4];
    const int cx = DPX_CAST(int, DPX_FLOOR((x - ox) * inv_cell));
    const int cy = DPX_CAST(int, DPX_FLOOR((y - oy) * inv_cell));
    const int cz = DPX_CAST(int, DPX_FLOOR((z - oz) * inv_cell));
    if (cx < -1 || cy < -1 || cz < -1 || cx > nx || cy > ny || cz > nz) continue;
    const real s2 = sigma * sigma;
    const real h_scale = DPX_CAST(real, 20) * inv_sigma * inv_sigma;
    for (int iz = DPX_MAX(cz - 1, 0); iz <= DPX_MIN(cz + 1, nz - 1); ++iz) {
      for (int iy = DPX_MAX(cy - 1, 0); iy <= DPX_MIN(cy + 1, ny - 1); ++iy) {
        const DPX_UINT row = cs_off + DPX_CAST(DPX_UINT, (iz * ny + iy) * nx);
        const int x0 = DPX_MAX(cx - 1, 0), x1 = DPX_MIN(cx + 1, nx - 1);
        if (x0 > x1) continue;
        /* cells x0..x1 of one row are contiguous in the sorted centres */
        const DPX_UINT b = cell_start[row + DPX_CAST(DPX_UINT, x0)] + c_off;
        const DPX_UINT e = cell_start[row + DPX_CAST(DPX_UINT, x1) + 1] + c_off;
        for (DPX_UINT j = b; j < e; ++j) {
          const real ux = x - centres[4 * j], uy = y - centres[4 * j + 1], uz = z - centres[4 * j + 2];
          const real d2 = ux * ux + uy * uy + uz * uz;
          if (d2 >= s2) continue;
          const real w = centres[4 * j + 3];
          const real rho = DPX_SQRT(d2);
          const real r = rho * inv_sigma;
          const real t = DPX_CAST(real, 1) - r;
          const real t2 = t * t;
          f += w * t2 * t2 * (DPX_CAST(real, 4) * r + DPX_CAST(real, 1));
          if (k >= 4) {
            const real g = -w * h_scale * t2 * t;
            gx += g * ux;
            gy += g * uy;
            gz += g * uz;
          }
          if (k >= 10) {
            const real a = w * h_scale * t2;
            const real c = rho > DPX_CAST(real, 0) ? DPX_CAST(real, 3) * r / d2 : DPX_CAST(real, 0);
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
  acc[0] = f;
  if (k >= 4) {
    acc[1] = gx;
    acc[2] = gy;
    acc[3] = gz;
  }
  if (k >= 10) {
    acc[4] = hxx;
    acc[5] = hxy;
    acc[6] = hxz;
    acc[7] = hyy;
    acc[8] = hyz;
    acc[9] = hzz;
  }
}

#undef DPX_FN
#undef DPX_GLOBAL
#undef DPX_UINT
#undef DPX_FLOOR
#undef DPX_SQRT
#undef DPX_MIN
#undef DPX_MAX
#undef DPX_CAST
