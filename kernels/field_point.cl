/* The field at one point (docs/method.md section 6): the ONE body of the evaluation loop, compiled both
 * as OpenCL C (the "field" program: common.cl, this file, eval_field.cl) and as C++ (included by
 * lib/field/field_evaluator.cpp, the reference device's twin, where `real` is a template parameter).
 *   f(x) = f0 + sum_levels sum_{|x - c_j| < sigma} w_j phi(|x - c_j| / sigma),  phi(r) = (1-r)^4 (4r+1)
 *   grad f = sum -w 20/sigma^2 (1-r)^3 u                                     (u = x - c_j)
 *   H      = sum  w 20/sigma^2 (1-r)^2 [3 r u u^T / |u|^2 - (1-r) I]         (first term 0 at u = 0)
 * Each level's centres are bucketed in a grid of cells at least sigma deep in y and z and an eighth of
 * that wide along x, so the 3 x 3 rows of cells around the query's (y, z) cell hold every centre within
 * the support, and in each row the cells that the support's x-extent reaches are one contiguous run of
 * the sorted centres (dpx_x_span): 2 1/8 sigma of each row instead of 3 sigma with cubic cells.
 *   params[7*L]   per level: origin x, y, z, 1/cell (y, z), sigma, 1/sigma, 1/cell (x)
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
#define DPX_PRIVATE __private
#else
#define DPX_FN template <typename real> inline
#define DPX_GLOBAL
#define DPX_UINT std::uint32_t
#define DPX_FLOOR std::floor
#define DPX_SQRT std::sqrt
#define DPX_MIN std::min
#define DPX_MAX std::max
#define DPX_CAST(type, value) static_cast<type>(value)
#define DPX_PRIVATE
#endif

/* The cells [*x0, *x1] along x (clamped to the level's nx; *x0 > *x1 when none) that the support of a
 * query at x reaches, from the level's parameters p. The extent is widened by sigma/1024 so that rounding
 * cannot drop a centre within it (every visited centre is still tested against the support). The
 * products are clamped before the conversion, so a query far outside the grid converts no out-of-range
 * value. */
DPX_FN void dpx_x_span(const real x, DPX_GLOBAL const real* p, const int nx, DPX_PRIVATE int* x0,
                       DPX_PRIVATE int* x1) {
  const real fx = (x - p[0]) * p[6];
  const real reach = p[4] * p[6] * DPX_CAST(real, 1.0009765625);
  *x0 = DPX_CAST(int, DPX_FLOOR(DPX_MIN(DPX_MAX(fx - reach, DPX_CAST(real, 0)), DPX_CAST(real, nx))));
  *x1 = DPX_CAST(int, DPX_FLOOR(DPX_MIN(DPX_MAX(fx + reach, DPX_CAST(real, -1)), DPX_CAST(real, nx - 1))));
}

DPX_FN void dpx_field_point(const real x, const real y, const real z, const DPX_UINT nlevels,
                            DPX_GLOBAL const real* params, DPX_GLOBAL const DPX_UINT* dims,
                            DPX_GLOBAL const DPX_UINT* cell_start, DPX_GLOBAL const real* centres,
                            const real f0, const int k, real* acc) {
  real f = f0;
  real gx = 0, gy = 0, gz = 0;
  real hxx = 0, hxy = 0, hxz = 0, hyy = 0, hyz = 0, hzz = 0;
  for (DPX_UINT l = 0; l < nlevels; ++l) {
    DPX_GLOBAL const real* p = params + 7 * l;
    const real oy = p[1], oz = p[2], inv_cell = p[3], sigma = p[4], inv_sigma = p[5];
    const int nx = DPX_CAST(int, dims[5 * l]), ny = DPX_CAST(int, dims[5 * l + 1]), nz = DPX_CAST(int, dims[5 * l + 2]);
    const DPX_UINT cs_off = dims[5 * l + 3], c_off = dims[5 * l + 4];
    const real fy = (y - oy) * inv_cell, fz = (z - oz) * inv_cell;
    if (!(fy >= DPX_CAST(real, -1) && fz >= DPX_CAST(real, -1) && fy < DPX_CAST(real, ny + 1) &&
          fz < DPX_CAST(real, nz + 1))) {
      continue;
    }
    int x0 = 0, x1 = -1;
    dpx_x_span(x, p, nx, &x0, &x1);
    if (x0 > x1) continue;
    const int cy = DPX_CAST(int, DPX_FLOOR(fy)), cz = DPX_CAST(int, DPX_FLOOR(fz));
    const real s2 = sigma * sigma;
    const real h_scale = DPX_CAST(real, 20) * inv_sigma * inv_sigma;
    for (int iz = DPX_MAX(cz - 1, 0); iz <= DPX_MIN(cz + 1, nz - 1); ++iz) {
      for (int iy = DPX_MAX(cy - 1, 0); iy <= DPX_MIN(cy + 1, ny - 1); ++iy) {
        const DPX_UINT row = cs_off + DPX_CAST(DPX_UINT, (iz * ny + iy) * nx);
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
#undef DPX_PRIVATE
