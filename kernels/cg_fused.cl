/* Fused updates of the preconditioned CG iteration (needs common.cl). With alpha = rz/pq:
 *   x <- x + alpha*p;  r <- r - alpha*q
 * and, in the same pass, the reductions the host needs next: r.z (z = dinv .* r, never stored; only
 * cg_update_*), r.r and max |r_i| (for the max-norm stopping test). cg_direction forms the next search
 * direction p <- dinv .* r + beta*p. Chunk variants are barrier-free (CPU); group variants reduce in
 * local memory (GPU; local size WG exactly). Partials per chunk/group: cg_update_* writes 3 values
 * (r.z, r.r, max|r|), cg_update_xr_* writes 2 (r.r, max|r|). */

/* Shared body: updates the elements of one chunk or one grid-stride walk and accumulates the three
 * reductions (dinv may be 0: no r.z). */
#define CG_UPDATE_BODY(I)                 \
  {                                       \
    x[I] += alpha * p[I];                 \
    const real ri = r[I] - alpha * q[I];  \
    r[I] = ri;                            \
    if (dinv) rz += ri * dinv[I] * ri;    \
    rr += ri * ri;                        \
    rmax = fmax(rmax, fabs(ri));          \
  }

inline void cg_chunk(const uint n, const real alpha, __global const real* restrict p,
                     __global const real* restrict q, __global const real* restrict dinv,
                     __global real* restrict x, __global real* restrict r, __global real* restrict partial,
                     const uint per) {
  const uint c = get_global_id(0);
  if ((ulong)c * CHUNK >= n) return;
  uint begin, end;
  chunk_range(c, n, &begin, &end);
  real rz = 0, rr = 0, rmax = 0;
  for (uint i = begin; i < end; ++i) CG_UPDATE_BODY(i)
  if (per == 3) partial[3 * c] = rz;
  partial[per * c + per - 2] = rr;
  partial[per * c + per - 1] = rmax;
}

inline void cg_group(const uint n, const real alpha, __global const real* restrict p,
                     __global const real* restrict q, __global const real* restrict dinv,
                     __global real* restrict x, __global real* restrict r, __global real* restrict partial,
                     const uint per, __local real* s_rz, __local real* s_rr, __local real* s_max) {
  real rz = 0, rr = 0, rmax = 0;
  for (uint i = get_global_id(0); i < n; i += get_global_size(0)) CG_UPDATE_BODY(i)
  const uint lid = get_local_id(0);
  s_rz[lid] = rz;
  s_rr[lid] = rr;
  s_max[lid] = rmax;
  for (uint stride = WG / 2; stride > 0; stride >>= 1) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < stride) {
      s_rz[lid] += s_rz[lid + stride];
      s_rr[lid] += s_rr[lid + stride];
      s_max[lid] = fmax(s_max[lid], s_max[lid + stride]);
    }
  }
  if (lid == 0) {
    const uint g = get_group_id(0);
    if (per == 3) partial[3 * g] = s_rz[0];
    partial[per * g + per - 2] = s_rr[0];
    partial[per * g + per - 1] = s_max[0];
  }
}

__kernel void cg_update_chunk(const uint n, const real alpha, __global const real* restrict p,
                              __global const real* restrict q, __global const real* restrict dinv,
                              __global real* restrict x, __global real* restrict r,
                              __global real* restrict partial) {
  cg_chunk(n, alpha, p, q, dinv, x, r, partial, 3);
}

__kernel void cg_update_group(const uint n, const real alpha, __global const real* restrict p,
                              __global const real* restrict q, __global const real* restrict dinv,
                              __global real* restrict x, __global real* restrict r,
                              __global real* restrict partial) {
  __local real s_rz[WG], s_rr[WG], s_max[WG];
  cg_group(n, alpha, p, q, dinv, x, r, partial, 3, s_rz, s_rr, s_max);
}

__kernel void cg_update_xr_chunk(const uint n, const real alpha, __global const real* restrict p,
                                 __global const real* restrict q, __global real* restrict x,
                                 __global real* restrict r, __global real* restrict partial) {
  cg_chunk(n, alpha, p, q, 0, x, r, partial, 2);
}

__kernel void cg_update_xr_group(const uint n, const real alpha, __global const real* restrict p,
                                 __global const real* restrict q, __global real* restrict x,
                                 __global real* restrict r, __global real* restrict partial) {
  __local real s_rz[WG], s_rr[WG], s_max[WG];
  cg_group(n, alpha, p, q, 0, x, r, partial, 2, s_rz, s_rr, s_max);
}

__kernel void cg_direction(const uint n, const real beta, __global const real* restrict r,
                           __global const real* restrict dinv, __global real* restrict p) {
  const uint i = get_global_id(0);
  if (i < n) p[i] = dinv[i] * r[i] + beta * p[i];
}
