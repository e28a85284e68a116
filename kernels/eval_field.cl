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
#define DPX_LANE_INDEX (maskv)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15)

inline real dpx_hsum(const realv v16) {
  const float8 v = v16.lo + v16.hi;
  const float4 h = v.lo + v.hi;
  return (h.s0 + h.s2) + (h.s1 + h.s3);
}
#elif FIELD_WIDTH == 8
typedef float8 realv;
typedef int8 maskv;
#define DPX_VLOAD vload8
#define DPX_LANE_INDEX (maskv)(0, 1, 2, 3, 4, 5, 6, 7)

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

inline void dpx_field_point_v8(const real x, const real y, const real z, const uint nlevels,
                               __global const real* params, __global const uint* dims,
                               __global const uint* cell_start, __global const real* centres, const real f0,
                               __global const uint* dlevel, __global const dreal* dcentres, const int k,
                               real* acc) {
#ifdef DPX_COARSE_DOUBLE
  double dsum[10] = {f0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  real sum[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  const dmaskv dlane = DPX_DLANE_INDEX;
  const double xd = x, yd = y, zd = z;
#else
  real sum[10] = {f0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
#endif
  const maskv lane = DPX_LANE_INDEX;
  for (uint l = 0; l < nlevels; ++l) {
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
#endif /* REAL_IS_DOUBLE */
