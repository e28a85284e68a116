/* BLAS-1 kernels. Element-wise kernels map one element to one work-item (global size rounded up to
 * the work-group size; guarded by n). Reductions come in two shapes:
 *  - *_chunk: barrier-free; work-item c owns elements [c*CHUNK, (c+1)*CHUNK) and writes partial[c]
 *    (fast on CPU devices such as PoCL, where barriers are expensive);
 *  - *_group: grid-stride loop per work-item, then a local-memory tree reduction; work-group g writes
 *    partial[g] (coalesced, for GPUs). Launch with local size WG exactly.
 * The host adds the partials in double. */

/* y <- alpha*x + y */
__kernel void axpy(const uint n, const real alpha, __global const real* restrict x,
                   __global real* restrict y) {
  const uint i = get_global_id(0);
  if (i < n) y[i] += alpha * x[i];
}

/* y <- x + beta*y */
__kernel void xpay(const uint n, __global const real* restrict x, const real beta,
                   __global real* restrict y) {
  const uint i = get_global_id(0);
  if (i < n) y[i] = x[i] + beta * y[i];
}

/* z <- d .* r (diagonal preconditioner apply) */
__kernel void vmul(const uint n, __global const real* restrict d, __global const real* restrict r,
                   __global real* restrict z) {
  const uint i = get_global_id(0);
  if (i < n) z[i] = d[i] * r[i];
}

/* partial[c] = sum of x_i*y_i over chunk c */
__kernel void dot_chunk(const uint n, __global const real* restrict x, __global const real* restrict y,
                        __global real* restrict partial) {
  const uint c = get_global_id(0);
  if ((ulong)c * CHUNK >= n) return;
  uint begin, end;
  chunk_range(c, n, &begin, &end);
  real s = 0;
  for (uint i = begin; i < end; ++i) s += x[i] * y[i];
  partial[c] = s;
}

/* partial[group] = sum of x_i*y_i over the elements the group's work-items visit */
__kernel void dot_group(const uint n, __global const real* restrict x, __global const real* restrict y,
                        __global real* restrict partial) {
  __local real s[WG];
  real acc = 0;
  for (uint i = get_global_id(0); i < n; i += get_global_size(0)) acc += x[i] * y[i];
  s[get_local_id(0)] = acc;
  group_reduce(s);
  if (get_local_id(0) == 0) partial[get_group_id(0)] = s[0];
}

/* a <- b + s*c (the STREAM triad; used by the benchmarks to measure the device's memory bandwidth) */
__kernel void triad(const uint n, __global real* restrict a, __global const real* restrict b,
                    __global const real* restrict c, const real s) {
  const uint i = get_global_id(0);
  if (i < n) a[i] = b[i] + s * c[i];
}
