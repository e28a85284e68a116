/* Evaluation of the multi-level CSRBF field (docs/method.md section 6) at query points (needs common.cl
 * and field_point.cl, whose dpx_field_point is the one body shared with the C++ reference twin).
 * One work-item per query; the _v8 kernels (CPU devices, below) sum 8 or 16 centres a step.
 * Arguments:
 *   nq, queries[3*nq]           query points (normalised coordinates)
 *   nlevels                     how many levels (from the first) to sum
 *   params, dims, cell_start, centres   the per-level grids (layout in field_point.cl; the _v8 kernels
 *                               take the centres as per-level x, y, z, w arrays, see below)
 *   f0                          the constant base field
 *   out[K*nq]                   K = 1 (f), 4 (f, df/dx, df/dy, df/dz) or 10 (f, gradient, Hessian
 *                               xx, xy, xz, yy, yz, zz), query-major */

/* One entry point: query q of work-item q, K results of the body `point` (dpx_field_point or, below,
 * dpx_field_point_v8). */
#define DPX_EVAL_KERNEL(name, point, K)                                                                  \
  __kernel void name(const uint nq, __global const real* queries, const uint nlevels,                    \
                     __global const real* params, __global const uint* dims,                             \
                     __global const uint* cell_start, __global const real* centres, const real f0,       \
                     __global real* out) {                                                               \
    const uint q = get_global_id(0);                                                                     \
    if (q >= nq) return;                                                                                 \
    real acc[10];                                                                                        \
    point(queries[3 * q], queries[3 * q + 1], queries[3 * q + 2], nlevels, params, dims, cell_start,     \
          centres, f0, K, acc);                                                                          \
    for (int c = 0; c < K; ++c) out[(ulong)K * q + (ulong)c] = acc[c];                                   \
  }

DPX_EVAL_KERNEL(eval_field_value, dpx_field_point, 1)
DPX_EVAL_KERNEL(eval_field_gradient, dpx_field_point, 4)
DPX_EVAL_KERNEL(eval_field_hessian, dpx_field_point, 10)

/* ---- The CPU devices' variant: FIELD_WIDTH (8 or 16) centres a step in SIMD registers ----
 * The same sum as dpx_field_point, term for term (the C++ reference twin and the brute-force oracle are
 * what the tests compare both kernels with); only the order of the additions differs: each of the
 * FIELD_WIDTH lanes keeps its own partial sums of a level, added to the running sum (which starts at f0)
 * at the end of the level. Near the surface the coarse levels cancel f0, so the small fine-level terms are
 * added to small sums, as in the scalar kernel (lane sums kept over all levels carry the coarse levels'
 * magnitude: in float, 1.7x the scalar kernel's largest error on fandisk_550k). PoCL runs one work-item's
 * loop over a row of centres as scalar code (the trip count differs between work-items, so it cannot
 * vectorise across them); here the loop itself is FIELD_WIDTH wide. The width is the device's native
 * float vector (LaunchParams::fieldWidth: 16 with AVX-512, where a row's few centres also take fewer
 * masked steps, else 8); the two widths add a level's terms in different orders, so their results differ
 * in float rounding only.
 * The centres come in the layout FieldEvaluator uploads for these kernels: level by level, four arrays
 * of the level's size n (x, y, z, then w), level l from 4 * its centre offset, so that each step reads
 * four contiguous vectors (vload8/vload16). Out of the x-y-z-w records of the scalar kernel PoCL built
 * each step from 8-byte loads and shuffles (docs/benchmarks.md). Lanes past the end of the row are
 * masked, so the buffer is allocated 32 reals longer than the centres (FieldEvaluator pads it; the values
 * there are never used).
 * Float only: in double, FieldEvaluator runs the scalar kernel. */
#ifndef REAL_IS_DOUBLE
#ifndef FIELD_WIDTH
#define FIELD_WIDTH 8
#endif
#if FIELD_WIDTH == 16
#ifdef __clang__
/* Without AVX-512 (DUPLEXFIT_FIELD_KERNEL=vector16 on an AVX2 CPU) clang warns that a float16 return
 * value changes the ABI; vload16 and dpx_hsum are inlined, so no call passes one. */
#pragma clang diagnostic ignored "-Wpsabi"
#endif
typedef float16 realv;
typedef int16 maskv;
#define DPX_VLOAD vload16
#define DPX_VSTORE vstore16
#define DPX_LANE_INDEX (maskv)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)

inline int dpx_isum(const maskv v16) {
  const int8 v = v16.lo + v16.hi;
  const int4 h = v.lo + v.hi;
  return (h.s0 + h.s2) + (h.s1 + h.s3);
}

inline real dpx_hsum(const realv v16) {
  const float8 v = v16.lo + v16.hi;
  const float4 h = v.lo + v.hi;
  return (h.s0 + h.s2) + (h.s1 + h.s3);
}
#elif FIELD_WIDTH == 8
typedef float8 realv;
typedef int8 maskv;
#define DPX_VLOAD vload8
#define DPX_VSTORE vstore8
#define DPX_LANE_INDEX (maskv)(0, 1, 2, 3, 4, 5, 6, 7)

inline int dpx_isum(const maskv v) {
  const int4 h = v.lo + v.hi;
  return (h.s0 + h.s2) + (h.s1 + h.s3);
}

inline real dpx_hsum(const realv v) {
  const float4 h = v.lo + v.hi;
  return (h.s0 + h.s2) + (h.s1 + h.s3);
}
#else
#error "FIELD_WIDTH must be 8 or 16"
#endif

/* ---- Coarse levels with large weights in double (DPX_COARSE_DOUBLE: devices with fp64) ----
 * A term w (1 - r)^4 (4r + 1) computed in float carries an error of about 1e-7 |w|, and the coarse levels'
 * weights are of order 1-10 (ill-conditioned ones up to 80): in float the sum's error floor was 2.8e-6
 * of the box on fandisk_550k and 4e-5 on thin_torus_20k, whatever the order of the additions. The
 * evaluator gives the levels with few centres whose largest |w| exceeds a bound (field_evaluator.cpp,
 * kDoubleLevelWeight, kDoubleLevelMaxCentres) a copy in double: dlevel[l] is the offset of level l's
 * block in dcentres (sigma, 1/sigma, then x, y, z, w arrays of the level's size in the float arrays'
 * order), 0xffffffff for a level summed in float. Those
 * levels are summed FIELD_WIDTH / 2 centres a step (the same register width), over the same runs of
 * cells, into sums kept in double that start at f0; the float levels' sums are added to them at the end. */
#ifdef DPX_COARSE_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
typedef double dreal;
#if FIELD_WIDTH == 16
typedef double8 dblv;
typedef long8 dmaskv;
#define DPX_DVLOAD vload8
#define DPX_DWIDTH 8
#define DPX_DLANE_INDEX (dmaskv)(0, 1, 2, 3, 4, 5, 6, 7)
typedef double16 dtilev; /* a tile's lanes in double (dpx_field_tile) */
typedef long16 dtilem;
#define DPX_DTILE convert_double16
#define DPX_DTILE_MASK convert_long16
#define DPX_DTILE_STORE vstore16
#define DPX_DVSTORE vstore8
inline int dpx_disum(const dmaskv v) {
  const long4 h = v.lo + v.hi;
  return (int)((h.s0 + h.s2) + (h.s1 + h.s3));
}
inline double dpx_dhsum(const dblv v) {
  const double4 h = v.lo + v.hi;
  return (h.s0 + h.s2) + (h.s1 + h.s3);
}
#else
typedef double4 dblv;
typedef long4 dmaskv;
#define DPX_DVLOAD vload4
#define DPX_DWIDTH 4
#define DPX_DLANE_INDEX (dmaskv)(0, 1, 2, 3)
typedef double8 dtilev;
typedef long8 dtilem;
#define DPX_DTILE convert_double8
#define DPX_DTILE_MASK convert_long8
#define DPX_DTILE_STORE vstore8
#define DPX_DVSTORE vstore4
inline int dpx_disum(const dmaskv v) { return (int)((v.s0 + v.s2) + (v.s1 + v.s3)); }
inline double dpx_dhsum(const dblv v) { return (v.s0 + v.s2) + (v.s1 + v.s3); }
#endif
#else
typedef real dreal; /* unused: no level is given a double block */
#endif

/* One level's terms at the query (XQ, YQ, ZQ): over its 3 x 3 rows of cells around (cy, cz), the cells
 * x0..x1 of each row (one contiguous run of centres), W centres a step in vectors VT (scalar ST, mask MT
 * built from the lane indices LANE compared as IT, loads VLOAD) from the arrays PX, PY, PZ, PW; the lanes'
 * sums (HSUM) are added to SUM[0..k). Lanes past the row (their values may be the next array's or the
 * padding) sit outside the support. The float levels and, with DPX_COARSE_DOUBLE, the double ones. */
#define DPX_LEVEL_SUM(ST, VT, MT, IT, VLOAD, W, LANE, HSUM, XQ, YQ, ZQ, PX, PY, PZ, PW, SIGMA, INV_SIGMA, SUM) \
  do {                                                                                                    \
    const ST sg_ = (SIGMA), isg_ = (INV_SIGMA);                                                           \
    const ST s2_ = sg_ * sg_;                                                                             \
    const ST hs_ = (ST)20 * isg_ * isg_;                                                                  \
    VT f_ = 0, gx_ = 0, gy_ = 0, gz_ = 0;                                                                 \
    VT hxx_ = 0, hxy_ = 0, hxz_ = 0, hyy_ = 0, hyz_ = 0, hzz_ = 0;                                        \
    for (int iz = max(cz - 1, 0); iz <= min(cz + 1, nz - 1); ++iz) {                                      \
      for (int iy = max(cy - 1, 0); iy <= min(cy + 1, ny - 1); ++iy) {                                    \
        const uint row = cs_off + (uint)((iz * ny + iy) * nx);                                            \
        const uint b = cell_start[row + (uint)x0];                                                        \
        const uint e = cell_start[row + (uint)x1 + 1];                                                    \
        for (uint j = b; j < e; j += (W)) {                                                               \
          const MT valid = (LANE) < (MT)((IT)(e - j));                                                    \
          const VT ux = select((VT)sg_, (XQ) - VLOAD(0, (PX) + j), valid);                                 \
          const VT uy = select((VT)sg_, (YQ) - VLOAD(0, (PY) + j), valid);                                 \
          const VT uz = select((VT)sg_, (ZQ) - VLOAD(0, (PZ) + j), valid);                                 \
          const VT d2 = ux * ux + uy * uy + uz * uz;                                                      \
          const MT inside = d2 < (VT)s2_;                                                                 \
          const VT w = select((VT)0, VLOAD(0, (PW) + j), inside);                                         \
          const VT rho = sqrt(d2);                                                                        \
          const VT r = rho * isg_;                                                                        \
          const VT t = fmax((VT)1 - r, (VT)0);                                                            \
          const VT t2 = t * t;                                                                            \
          f_ += w * t2 * t2 * ((VT)4 * r + (VT)1);                                                        \
          if (k >= 4) {                                                                                   \
            const VT g = -w * hs_ * t2 * t;                                                               \
            gx_ += g * ux;                                                                                \
            gy_ += g * uy;                                                                                \
            gz_ += g * uz;                                                                                \
          }                                                                                               \
          if (k >= 10) {                                                                                  \
            const VT a = w * hs_ * t2;                                                                    \
            const VT c = select((VT)0, (VT)3 * r / d2, rho > (VT)0);                                      \
            hxx_ += a * (c * ux * ux - t);                                                                \
            hyy_ += a * (c * uy * uy - t);                                                                \
            hzz_ += a * (c * uz * uz - t);                                                                \
            hxy_ += a * c * ux * uy;                                                                      \
            hxz_ += a * c * ux * uz;                                                                      \
            hyz_ += a * c * uy * uz;                                                                      \
          }                                                                                               \
        }                                                                                                 \
      }                                                                                                   \
    }                                                                                                     \
    (SUM)[0] += HSUM(f_);                                                                                 \
    if (k >= 4) {                                                                                         \
      (SUM)[1] += HSUM(gx_);                                                                              \
      (SUM)[2] += HSUM(gy_);                                                                              \
      (SUM)[3] += HSUM(gz_);                                                                              \
    }                                                                                                     \
    if (k >= 10) {                                                                                        \
      (SUM)[4] += HSUM(hxx_);                                                                             \
      (SUM)[5] += HSUM(hxy_);                                                                             \
      (SUM)[6] += HSUM(hxz_);                                                                             \
      (SUM)[7] += HSUM(hyy_);                                                                             \
      (SUM)[8] += HSUM(hyz_);                                                                             \
      (SUM)[9] += HSUM(hzz_);                                                                             \
    }                                                                                                     \
  } while (0)

/* Levels [l0, l1) of the sum at (x, y, z), added to sum[0..k) (the float levels) and, with
 * DPX_COARSE_DOUBLE, dsum[0..k) (the double levels). */
__attribute__((always_inline)) inline void dpx_field_levels_v8(const real x, const real y, const real z,
                                                               const uint l0, const uint l1,
                                                               __global const real* params,
                                                               __global const uint* dims,
                                                               __global const uint* cell_start,
                                                               __global const real* centres,
                                                               __global const uint* dlevel,
                                                               __global const dreal* dcentres, const int k,
                                                               real* sum, dreal* dsum) {
#ifdef DPX_COARSE_DOUBLE
  const dmaskv dlane = DPX_DLANE_INDEX;
  const double xd = x, yd = y, zd = z;
#endif
  const maskv lane = DPX_LANE_INDEX;
  for (uint l = l0; l < l1; ++l) {
    __global const real* p = params + 7 * l;
    const real oy = p[1], oz = p[2], inv_cell = p[3], sigma = p[4], inv_sigma = p[5];
    const int nx = (int)dims[5 * l], ny = (int)dims[5 * l + 1], nz = (int)dims[5 * l + 2];
    const uint cs_off = dims[5 * l + 3], c_off = dims[5 * l + 4];
    const uint n = cell_start[cs_off + (uint)(nx * ny * nz)]; /* the level's centres */
    __global const real* px = centres + 4 * (ulong)c_off;
    __global const real* py = px + n;
    __global const real* pz = py + n;
    __global const real* pw = pz + n;
    const real fy = (y - oy) * inv_cell, fz = (z - oz) * inv_cell;
    if (!(fy >= (real)-1 && fz >= (real)-1 && fy < (real)(ny + 1) && fz < (real)(nz + 1))) continue;
    int x0 = 0, x1 = -1;
    dpx_x_span(x, p, nx, &x0, &x1);
    if (x0 > x1) continue;
    const int cy = (int)floor(fy), cz = (int)floor(fz);
#ifdef DPX_COARSE_DOUBLE
    if (dlevel[l] != 0xffffffffu) {
      __global const double* dc = dcentres + dlevel[l];
      __global const double* qx = dc + 2;
      DPX_LEVEL_SUM(double, dblv, dmaskv, long, DPX_DVLOAD, DPX_DWIDTH, dlane, dpx_dhsum, xd, yd, zd, qx, qx + n,
                    qx + 2 * n, qx + 3 * n, dc[0], dc[1], dsum);
      continue;
    }
#endif
    DPX_LEVEL_SUM(real, realv, maskv, int, DPX_VLOAD, FIELD_WIDTH, lane, dpx_hsum, x, y, z, px, py, pz, pw, sigma,
                  inv_sigma, sum);
  }
}

inline void dpx_field_point_v8(const real x, const real y, const real z, const uint nlevels,
                               __global const real* params, __global const uint* dims,
                               __global const uint* cell_start, __global const real* centres, const real f0,
                               __global const uint* dlevel, __global const dreal* dcentres, const int k,
                               real* acc) {
#ifdef DPX_COARSE_DOUBLE
  double dsum[10] = {f0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  real sum[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
#else
  real sum[10] = {f0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  dreal dsum[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0}; /* unused */
#endif
  dpx_field_levels_v8(x, y, z, 0, nlevels, params, dims, cell_start, centres, dlevel, dcentres, k, sum, dsum);
#ifdef DPX_COARSE_DOUBLE
  for (int c = 0; c < k; ++c) acc[c] = (real)(dsum[c] + (double)sum[c]);
#else
  for (int c = 0; c < k; ++c) acc[c] = sum[c];
#endif
}

/* The _v8 entry points: the arguments of DPX_EVAL_KERNEL's and, before out, dlevel and dcentres. */
#define DPX_EVAL_KERNEL_V8(name, K)                                                                      \
  __kernel void name(const uint nq, __global const real* queries, const uint nlevels,                    \
                     __global const real* params, __global const uint* dims,                             \
                     __global const uint* cell_start, __global const real* centres, const real f0,       \
                     __global const uint* dlevel, __global const dreal* dcentres, __global real* out) {  \
    const uint q = get_global_id(0);                                                                     \
    if (q >= nq) return;                                                                                 \
    real acc[10];                                                                                        \
    dpx_field_point_v8(queries[3 * q], queries[3 * q + 1], queries[3 * q + 2], nlevels, params, dims,    \
                       cell_start, centres, f0, dlevel, dcentres, K, acc);                               \
    for (int c = 0; c < K; ++c) out[(ulong)K * q + (ulong)c] = acc[c];                                   \
  }

DPX_EVAL_KERNEL_V8(eval_field_value_v8, 1)
DPX_EVAL_KERNEL_V8(eval_field_gradient_v8, 4)
DPX_EVAL_KERNEL_V8(eval_field_hessian_v8, 10)

/* ---- Tiles: FIELD_WIDTH queries a work-item, one a lane, for the coarse levels ----
 * A query's coarse levels cost as much as its fine ones (each level has about as many centres within
 * reach of a surface point: 24-100 on fandisk_550k's field), but a coarse support is much wider than the
 * distance between neighbouring queries of a mesh, a grid block or a Morton-ordered batch. So the levels
 * [0, ntile) are summed for a tile of FIELD_WIDTH consecutive queries at once: the cells within sigma of the
 * tile's box are read once, FIELD_WIDTH centres at a time; a centre is kept when it lies within sigma of
 * the box (a vector test, the kept ones listed from a bit mask), and its terms are then computed for all
 * the tile's queries in one vector step, each lane adding them in the centres' order (terms outside a
 * lane's support are +0, which add nothing). Where the tile's box is wider than DPX_TILE_SPAN sigma in some
 * axis, its halves, else its quarters, are summed so with the other lanes masked; a quarter still wider
 * (scattered queries) is summed a query at a time, W centres a step, each term within the support added on
 * its own in the same order (DPX_SEQ_SUM): the same bits. So a query's value does not depend on the other
 * queries of its batch or on their order. The levels [ntile, nlevels) are summed per query as in the _v8
 * kernels. Value (K = 1) and gradient (K = 4). */
#ifndef DPX_TILE_SPAN
#define DPX_TILE_SPAN 1.0f
#endif

#define DPX_TILE_STEP(ST, VT, MT, QX, QY, QZ, ACTIVE, CX, CY, CZ, WC, S2, ISG, HS, F, GX, GY, GZ)             \
  do {                                                                                                      \
    const VT ux = (QX) - (CX), uy = (QY) - (CY), uz = (QZ) - (CZ);                                          \
    const VT d2 = ux * ux + uy * uy + uz * uz;                                                              \
    const MT inside = (d2 < (VT)(S2)) & (ACTIVE);                                                           \
    const VT w = select((VT)0, (VT)(WC), inside);                                                           \
    const VT r = sqrt(d2) * (ISG);                                                                          \
    const VT t = fmax((VT)1 - r, (VT)0);                                                                    \
    const VT t2 = t * t;                                                                                    \
    const VT ft = w * t2 * t2 * ((VT)4 * r + (VT)1);                                                        \
    (F) += ft;                                                                                              \
    if (k >= 4) {                                                                                           \
      const VT g = -w * (HS) * t2 * t;                                                                      \
      const VT gxt = g * ux, gyt = g * uy, gzt = g * uz;                                                    \
      (GX) += gxt;                                                                                          \
      (GY) += gyt;                                                                                          \
      (GZ) += gzt;                                                                                          \
    }                                                                                                       \
  } while (0)

/* One query's level, W centres a step with the terms of DPX_TILE_STEP, each term within the support added to
 * S[0..k) on its own, in the centres' order: the sum that a tile's lane makes of the same level (the terms
 * outside its support it adds are +0), so a query gets the same bits whether its tile is wide or not. Rows
 * [ty0, ty1] x [tz0, tz1], cells [tx0, tx1]. */
#define DPX_SEQ_SUM(ST, VT, MT, IT, VLOAD, VSTORE, W, LANE, ISUM, XQ, YQ, ZQ, PX, PY, PZ, PW, SIGMA, INV_SIGMA,  \
                    S)                                                                                      \
  do {                                                                                                      \
    const ST sg_ = (SIGMA), isg_ = (INV_SIGMA);                                                             \
    const ST s2_ = sg_ * sg_;                                                                               \
    const ST hs_ = (ST)20 * isg_ * isg_;                                                                    \
    for (int iz = tz0; iz <= tz1; ++iz) {                                                                   \
      for (int iy = ty0; iy <= ty1; ++iy) {                                                                 \
        const uint row = cs_off + (uint)((iz * ny + iy) * nx);                                              \
        const uint b = cell_start[row + (uint)tx0];                                                         \
        const uint e = cell_start[row + (uint)tx1 + 1];                                                     \
        for (uint j0 = b; j0 < e; j0 += (W)) {                                                              \
          const MT valid = (LANE) < (MT)((IT)(e - j0));                                                     \
          const VT ux = select((VT)sg_, (VT)(XQ) - VLOAD(0, (PX) + j0), valid);                             \
          const VT uy = select((VT)sg_, (VT)(YQ) - VLOAD(0, (PY) + j0), valid);                             \
          const VT uz = select((VT)sg_, (VT)(ZQ) - VLOAD(0, (PZ) + j0), valid);                             \
          const VT d2 = ux * ux + uy * uy + uz * uz;                                                        \
          const MT inside = d2 < (VT)s2_;                                                                   \
          int bits_ = ISUM(select((MT)0, (MT)1 << (LANE), inside));                                         \
          if (bits_ == 0) continue;                                                                         \
          const VT w = select((VT)0, VLOAD(0, (PW) + j0), inside);                                          \
          const VT r = sqrt(d2) * isg_;                                                                     \
          const VT t = fmax((VT)1 - r, (VT)0);                                                              \
          const VT t2 = t * t;                                                                              \
          const VT ft = w * t2 * t2 * ((VT)4 * r + (VT)1);                                                  \
          ST a_[4][W];                                                                                      \
          VSTORE(ft, 0, a_[0]);                                                                             \
          if (k >= 4) {                                                                                     \
            const VT g = -w * hs_ * t2 * t;                                                                 \
            const VT gxt = g * ux, gyt = g * uy, gzt = g * uz;                                              \
            VSTORE(gxt, 0, a_[1]);                                                                          \
            VSTORE(gyt, 0, a_[2]);                                                                          \
            VSTORE(gzt, 0, a_[3]);                                                                          \
          }                                                                                                 \
          while (bits_ != 0) {                                                                              \
            const int i_ = 31 - clz(bits_ & -bits_);                                                        \
            bits_ &= bits_ - 1;                                                                             \
            (S)[0] += a_[0][i_];                                                                            \
            if (k >= 4) {                                                                                   \
              (S)[1] += a_[1][i_];                                                                          \
              (S)[2] += a_[2][i_];                                                                          \
              (S)[3] += a_[3][i_];                                                                          \
            }                                                                                               \
          }                                                                                                 \
        }                                                                                                   \
      }                                                                                                     \
    }                                                                                                       \
  } while (0)

/* A level's lane sums f_, gx_, gy_, gz_ added to the tile's running sums. */
#define DPX_TILE_ADD(F, GX, GY, GZ) \
  do {                              \
    (F) += f_;                      \
    if (k >= 4) {                   \
      (GX) += gx_;                  \
      (GY) += gy_;                  \
      (GZ) += gz_;                  \
    }                               \
  } while (0)

/* A float level over the tile: the cells' centres FIELD_WIDTH at a time, kept by a vector test
 * of their distance to the box [LO, HI] and listed without branches, then one step each. */
#define DPX_TILE_SUM(LOX, LOY, LOZ, HIX, HIY, HIZ, ACTIVE, PX, PY, PZ, PW, SIGMA, INV_SIGMA, F, GX, GY, GZ)   \
  do {                                                                                                      \
    const real sg_ = (SIGMA), isg_ = (INV_SIGMA);                                                           \
    const real s2_ = sg_ * sg_;                                                                             \
    const realv keep_ = (realv)(s2_ * (real)1.001);                                                         \
    const real hs_ = (real)20 * isg_ * isg_;                                                                \
    realv f_ = 0, gx_ = 0, gy_ = 0, gz_ = 0;                                                                \
    for (int iz = tz0; iz <= tz1; ++iz) {                                                                   \
      for (int iy = ty0; iy <= ty1; ++iy) {                                                                 \
        const uint row = cs_off + (uint)((iz * ny + iy) * nx);                                              \
        const uint b = cell_start[row + (uint)tx0];                                                         \
        const uint e = cell_start[row + (uint)tx1 + 1];                                                     \
        for (uint j0 = b; j0 < e; j0 += FIELD_WIDTH) {                                                      \
          const maskv valid_ = lane < (maskv)((int)(e - j0));                                               \
          const realv cx_ = DPX_VLOAD(0, (PX) + j0), cy_ = DPX_VLOAD(0, (PY) + j0);                         \
          const realv cz_ = DPX_VLOAD(0, (PZ) + j0);                                                        \
          const realv ex_ = fmax(fmax((realv)(LOX) - cx_, cx_ - (realv)(HIX)), (realv)0);                   \
          const realv ey_ = fmax(fmax((realv)(LOY) - cy_, cy_ - (realv)(HIY)), (realv)0);                   \
          const realv ez_ = fmax(fmax((realv)(LOZ) - cz_, cz_ - (realv)(HIZ)), (realv)0);                   \
          const maskv pass_ = (ex_ * ex_ + ey_ * ey_ + ez_ * ez_ < keep_) & valid_;                         \
          int bits_ = dpx_isum(select((maskv)0, (maskv)1 << lane, pass_));                                 \
          while (bits_ != 0) {                                                                              \
            const uint j = j0 + (uint)(31 - clz(bits_ & -bits_));                                           \
            bits_ &= bits_ - 1;                                                                             \
            DPX_TILE_STEP(real, realv, maskv, qx, qy, qz, ACTIVE, (PX)[j], (PY)[j], (PZ)[j], (PW)[j], s2_,   \
                          isg_, hs_, f_, gx_, gy_, gz_);                                                    \
          }                                                                                                 \
        }                                                                                                   \
      }                                                                                                     \
    }                                                                                                       \
    DPX_TILE_ADD(F, GX, GY, GZ);                                                                            \
  } while (0)

/* A double level (few centres, most of them within reach): every centre of the cells, one step each. */
#define DPX_TILE_SUM_D(ACTIVE, PX, PY, PZ, PW, SIGMA, INV_SIGMA, F, GX, GY, GZ)                              \
  do {                                                                                                      \
    const double sg_ = (SIGMA), isg_ = (INV_SIGMA);                                                         \
    const double s2_ = sg_ * sg_;                                                                           \
    const double hs_ = 20.0 * isg_ * isg_;                                                                  \
    dtilev f_ = 0, gx_ = 0, gy_ = 0, gz_ = 0;                                                               \
    for (int iz = tz0; iz <= tz1; ++iz) {                                                                   \
      for (int iy = ty0; iy <= ty1; ++iy) {                                                                 \
        const uint row = cs_off + (uint)((iz * ny + iy) * nx);                                              \
        const uint b = cell_start[row + (uint)tx0];                                                         \
        const uint e = cell_start[row + (uint)tx1 + 1];                                                     \
        for (uint j = b; j < e; ++j) {                                                                      \
          DPX_TILE_STEP(double, dtilev, dtilem, dqx, dqy, dqz, ACTIVE, (PX)[j], (PY)[j], (PZ)[j], (PW)[j],  \
                        s2_, isg_, hs_, f_, gx_, gy_, gz_);                                                 \
        }                                                                                                   \
      }                                                                                                     \
    }                                                                                                       \
    DPX_TILE_ADD(F, GX, GY, GZ);                                                                            \
  } while (0)

/* The cells [*c0, *c1] of an axis with n cells (origin o, 1/cell inv) that [lo - reach, hi + reach] meets
 * (*c0 > *c1 when none), clamped before the conversion so that no value overflows an int. */
inline void dpx_cell_range(const real lo, const real hi, const real reach, const real o, const real inv,
                           const int n, int* c0, int* c1) {
  const real f0 = (lo - reach - o) * inv, f1 = (hi + reach - o) * inv;
  *c0 = (int)floor(fmin(fmax(f0, (real)0), (real)n));
  *c1 = (int)floor(fmin(fmax(f1, (real)-1), (real)(n - 1)));
}

/* Always inlined, as dpx_field_levels_v8, so that k is a constant in each kernel. */
__attribute__((always_inline)) inline void dpx_field_tile(const uint nq, __global const real* queries,
                                                          const uint nlevels, __global const real* params,
                                                          __global const uint* dims,
                                                          __global const uint* cell_start,
                                                          __global const real* centres, const real f0,
                                                          __global const uint* dlevel,
                                                          __global const dreal* dcentres, const uint ntile,
                                                          const int k, __global real* out) {
  const uint first = (uint)get_global_id(0) * FIELD_WIDTH;
  if (first >= nq) return;
  const int count = (int)min((uint)FIELD_WIDTH, nq - first);
  real ax[FIELD_WIDTH], ay[FIELD_WIDTH], az[FIELD_WIDTH];
  for (int i = 0; i < FIELD_WIDTH; ++i) {
    const uint q = first + (uint)min(i, count - 1); /* lanes past the batch repeat its last query */
    ax[i] = queries[3 * q];
    ay[i] = queries[3 * q + 1];
    az[i] = queries[3 * q + 2];
  }
  const realv qx = DPX_VLOAD(0, ax), qy = DPX_VLOAD(0, ay), qz = DPX_VLOAD(0, az);
  const maskv lane = DPX_LANE_INDEX;
  /* A non-finite query only ever joins its own lane's sums (its NaN or infinite terms stay in its lane, and
   * an infinite coordinate reaches no cell). */
  const uint nt = min(ntile, nlevels);
#ifdef DPX_COARSE_DOUBLE
  const dtilev dqx = DPX_DTILE(qx), dqy = DPX_DTILE(qy), dqz = DPX_DTILE(qz);
  dtilev DF = (dtilev)f0, DGX = 0, DGY = 0, DGZ = 0;
  realv F = 0;
#else
  realv F = (realv)f0;
#endif
  realv GX = 0, GY = 0, GZ = 0;
  for (uint l = 0; l < nt; ++l) {
    __global const real* p = params + 7 * l;
    const real ox = p[0], oy = p[1], oz = p[2], inv_cell = p[3], sigma = p[4], inv_sigma = p[5], inv_cx = p[6];
    const int nx = (int)dims[5 * l], ny = (int)dims[5 * l + 1], nz = (int)dims[5 * l + 2];
    const uint cs_off = dims[5 * l + 3], c_off = dims[5 * l + 4];
    const uint n = cell_start[cs_off + (uint)(nx * ny * nz)];
    const real reach = sigma * (real)1.0009765625;
    const real span = DPX_TILE_SPAN * sigma;
    __global const real* px = centres + 4 * (ulong)c_off;
#ifdef DPX_COARSE_DOUBLE
    const bool dlev = dlevel[l] != 0xffffffffu; /* a level summed in double: its block in dcentres */
    __global const double* dc = dcentres + (dlev ? dlevel[l] : 0u);
    __global const double* cxs = dc + 2;
#endif
    int ty0, ty1, tz0, tz1, tx0, tx1;
    /* Groups of lanes: the whole tile, else its halves, else its quarters (consecutive queries lie close in
     * the batch's Morton order), each summed as a tile with the other lanes masked where its box fits in
     * DPX_TILE_SPAN sigma, else a query at a time. */
    for (int g0 = 0; g0 < count;) {
      int size = FIELD_WIDTH;
      while (g0 % size != 0) size /= 2;
      for (;; size /= 2) {
        const int g1 = min(g0 + size, count);
        real gx0 = ax[g0], gy0 = ay[g0], gz0 = az[g0], gx1 = ax[g0], gy1 = ay[g0], gz1 = az[g0];
        for (int i = g0 + 1; i < g1; ++i) {
          gx0 = fmin(gx0, ax[i]), gy0 = fmin(gy0, ay[i]), gz0 = fmin(gz0, az[i]);
          gx1 = fmax(gx1, ax[i]), gy1 = fmax(gy1, ay[i]), gz1 = fmax(gz1, az[i]);
        }
        if (gx1 - gx0 <= span && gy1 - gy0 <= span && gz1 - gz0 <= span) {
          const maskv active = lane >= (maskv)g0 & lane < (maskv)g1;
          g0 = g1;
          /* Rows within sigma of the box; a cell is at least sigma deep in y and z, so these hold every
           * row dpx_field_levels_v8 visits with a centre in a query's support. */
          dpx_cell_range(gy0, gy1, reach, oy, inv_cell, ny, &ty0, &ty1);
          dpx_cell_range(gz0, gz1, reach, oz, inv_cell, nz, &tz0, &tz1);
          dpx_cell_range(gx0, gx1, reach, ox, inv_cx, nx, &tx0, &tx1);
          if (ty0 > ty1 || tz0 > tz1 || tx0 > tx1) break;
#ifdef DPX_COARSE_DOUBLE
          if (dlev) {
            DPX_TILE_SUM_D(DPX_DTILE_MASK(active), cxs, cxs + n, cxs + 2 * n, cxs + 3 * n, dc[0], dc[1], DF, DGX,
                           DGY, DGZ);
            break;
          }
#endif
          DPX_TILE_SUM(gx0, gy0, gz0, gx1, gy1, gz1, active, px, px + n, px + 2 * n, px + 3 * n, sigma, inv_sigma, F,
                       GX, GY, GZ);
          break;
        }
        if (size > FIELD_WIDTH / 4) continue;
        /* A quarter still wider than its level's reach (scattered queries): a query at a time, the same
         * sum. */
        for (int i = g0; i < g1; ++i) {
          dpx_cell_range(ay[i], ay[i], reach, oy, inv_cell, ny, &ty0, &ty1);
          dpx_cell_range(az[i], az[i], reach, oz, inv_cell, nz, &tz0, &tz1);
          dpx_cell_range(ax[i], ax[i], reach, ox, inv_cx, nx, &tx0, &tx1);
          if (ty0 > ty1 || tz0 > tz1 || tx0 > tx1) continue;
          const maskv at = lane == (maskv)i;
#ifdef DPX_COARSE_DOUBLE
          if (dlev) {
            const dmaskv dlane = DPX_DLANE_INDEX;
            double ds[4] = {0, 0, 0, 0};
            DPX_SEQ_SUM(double, dblv, dmaskv, long, DPX_DVLOAD, DPX_DVSTORE, DPX_DWIDTH, dlane, dpx_disum,
                        (double)ax[i], (double)ay[i], (double)az[i], cxs, cxs + n, cxs + 2 * n, cxs + 3 * n, dc[0],
                        dc[1], ds);
            const dtilem dat = DPX_DTILE_MASK(at);
            DF += select((dtilev)0, (dtilev)ds[0], dat);
            if (k >= 4) {
              DGX += select((dtilev)0, (dtilev)ds[1], dat);
              DGY += select((dtilev)0, (dtilev)ds[2], dat);
              DGZ += select((dtilev)0, (dtilev)ds[3], dat);
            }
            continue;
          }
#endif
          real fs[4] = {0, 0, 0, 0};
          DPX_SEQ_SUM(real, realv, maskv, int, DPX_VLOAD, DPX_VSTORE, FIELD_WIDTH, lane, dpx_isum, ax[i], ay[i], az[i],
                      px, px + n, px + 2 * n, px + 3 * n, sigma, inv_sigma, fs);
          F += select((realv)0, (realv)fs[0], at);
          if (k >= 4) {
            GX += select((realv)0, (realv)fs[1], at);
            GY += select((realv)0, (realv)fs[2], at);
            GZ += select((realv)0, (realv)fs[3], at);
          }
        }
        g0 = g1;
        break;
      }
    }
  }
  real tf[FIELD_WIDTH], tgx[FIELD_WIDTH], tgy[FIELD_WIDTH], tgz[FIELD_WIDTH];
  DPX_VSTORE(F, 0, tf);
  DPX_VSTORE(GX, 0, tgx);
  DPX_VSTORE(GY, 0, tgy);
  DPX_VSTORE(GZ, 0, tgz);
#ifdef DPX_COARSE_DOUBLE
  double df[FIELD_WIDTH], dgx[FIELD_WIDTH], dgy[FIELD_WIDTH], dgz[FIELD_WIDTH];
  DPX_DTILE_STORE(DF, 0, df);
  DPX_DTILE_STORE(DGX, 0, dgx);
  DPX_DTILE_STORE(DGY, 0, dgy);
  DPX_DTILE_STORE(DGZ, 0, dgz);
#endif
  for (int i = 0; i < count; ++i) {
    real sum[10] = {tf[i], tgx[i], tgy[i], tgz[i], 0, 0, 0, 0, 0, 0};
#ifdef DPX_COARSE_DOUBLE
    double dsum[10] = {df[i], dgx[i], dgy[i], dgz[i], 0, 0, 0, 0, 0, 0};
#else
    dreal dsum[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0}; /* unused */
#endif
    dpx_field_levels_v8(ax[i], ay[i], az[i], nt, nlevels, params, dims, cell_start, centres, dlevel, dcentres, k,
                        sum, dsum);
    const ulong q = first + (uint)i;
    for (int c = 0; c < k; ++c) {
#ifdef DPX_COARSE_DOUBLE
      out[(ulong)k * q + (ulong)c] = (real)(dsum[c] + (double)sum[c]);
#else
      out[(ulong)k * q + (ulong)c] = sum[c];
#endif
    }
  }
}

__kernel void eval_field_value_tile(const uint nq, __global const real* queries, const uint nlevels,
                                    __global const real* params, __global const uint* dims,
                                    __global const uint* cell_start, __global const real* centres, const real f0,
                                    __global const uint* dlevel, __global const dreal* dcentres, const uint ntile,
                                    __global real* out) {
  dpx_field_tile(nq, queries, nlevels, params, dims, cell_start, centres, f0, dlevel, dcentres, ntile, 1, out);
}

__kernel void eval_field_gradient_tile(const uint nq, __global const real* queries, const uint nlevels,
                                       __global const real* params, __global const uint* dims,
                                       __global const uint* cell_start, __global const real* centres,
                                       const real f0, __global const uint* dlevel,
                                       __global const dreal* dcentres, const uint ntile, __global real* out) {
  dpx_field_tile(nq, queries, nlevels, params, dims, cell_start, centres, f0, dlevel, dcentres, ntile, 4, out);
}
#endif /* REAL_IS_DOUBLE */
