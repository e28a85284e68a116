/* Evaluation of the multi-level CSRBF field (docs/method.md section 6) at query points (needs common.cl
 * and field_point.cl, whose dpx_field_point is the one body shared with the C++ reference twin).
 * One work-item per query.
 * Arguments:
 *   nq, queries[3*nq]           query points (normalised coordinates)
 *   nlevels                     how many levels (from the first) to sum
 *   params, dims, cell_start, centres   the per-level grids (layout in field_point.cl)
 *   f0                          the constant base field
 *   out[K*nq]                   K = 1 (f), 4 (f, df/dx, df/dy, df/dz) or 10 (f, gradient, Hessian
 *                               xx, xy, xz, yy, yz, zz), query-major */

inline void eval_point(const uint q, __global const real* queries, const uint nlevels,
                       __global const real* params, __global const uint* dims,
                       __global const uint* cell_start, __global const real* centres,
                       const real f0, __global real* out, const int k) {
  real acc[10];
  dpx_field_point(queries[3 * q], queries[3 * q + 1], queries[3 * q + 2], nlevels, params, dims,
                  cell_start, centres, f0, k, acc);
  for (int c = 0; c < k; ++c) out[(ulong)k * q + (ulong)c] = acc[c];
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
