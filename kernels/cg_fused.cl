/* Fused updates of the Jacobi-preconditioned CG iteration (needs common.cl). With alpha = rz/pq:
 *   x <- x + alpha*p;  r <- r - alpha*q;  z = dinv .* r (never stored)
 * and the two reductions r.z and r.r in the same pass. The next search direction
 *   p <- dinv .* r + beta*p
 * is cg_direction. Chunk variants are barrier-free (CPU); group variants reduce in local memory
 * (GPU; local size WG exactly). partial holds two values per chunk/group: [2c] = r.z, [2c+1] = r.r. */

__kernel void cg_update_chunk(const uint n, const real alpha, __global const real* restrict p,
                              __global const real* restrict q, __global const real* restrict dinv,
                              __global real* restrict x, __global real* restrict r,
                              __global real* restrict partial) {
  const uint c = get_global_id(0);
  if ((ulong)c * CHUNK >= n) return;
  uint begin, end;
  chunk_range(c, n, &begin, &end);
  real rz = 0, rr = 0;
  for (uint i = begin; i < end; ++i) {
    x[i] += alpha * p[i];
    const real ri = r[i] - alpha * q[i];
    r[i] = ri;
    rz += ri * dinv[i] * ri;
    rr += ri * ri;
  }
  partial[2 * c] = rz;
  partial[2 * c + 1] = rr;
}

__kernel void cg_update_group(const uint n, const real alpha, __global const real* restrict p,
                              __global const real* restrict q, __global const real* restrict dinv,
                              __global real* restrict x, __global real* restrict r,
                              __global real* restrict partial) {
  __local real s_rz[WG];
  __local real s_rr[WG];
  real rz = 0, rr = 0;
  for (uint i = get_global_id(0); i < n; i += get_global_size(0)) {
    x[i] += alpha * p[i];
    const real ri = r[i] - alpha * q[i];
    r[i] = ri;
    rz += ri * dinv[i] * ri;
    rr += ri * ri;
  }
  const uint lid = get_local_id(0);
  s_rz[lid] = rz;
  s_rr[lid] = rr;
  for (uint stride = WG / 2; stride > 0; stride >>= 1) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < stride) {
      s_rz[lid] += s_rz[lid + stride];
      s_rr[lid] += s_rr[lid + stride];
    }
  }
  if (lid == 0) {
    partial[2 * get_group_id(0)] = s_rz[0];
    partial[2 * get_group_id(0) + 1] = s_rr[0];
  }
}

__kernel void cg_direction(const uint n, const real beta, __global const real* restrict r,
                           __global const real* restrict dinv, __global real* restrict p) {
  const uint i = get_global_id(0);
  if (i < n) p[i] = dinv[i] * r[i] + beta * p[i];
}

/* The same update without a diagonal preconditioner (for block or other preconditioners, which apply
 * M^-1 in their own pass): x <- x + alpha*p; r <- r - alpha*q; partial[c] = r.r over the chunk/group. */
__kernel void cg_update_xr_chunk(const uint n, const real alpha, __global const real* restrict p,
                                 __global const real* restrict q, __global real* restrict x,
                                 __global real* restrict r, __global real* restrict partial) {
  const uint c = get_global_id(0);
  if ((ulong)c * CHUNK >= n) return;
  uint begin, end;
  chunk_range(c, n, &begin, &end);
  real rr = 0;
  for (uint i = begin; i < end; ++i) {
    x[i] += alpha * p[i];
    const real ri = r[i] - alpha * q[i];
    r[i] = ri;
    rr += ri * ri;
  }
  partial[c] = rr;
}

__kernel void cg_update_xr_group(const uint n, const real alpha, __global const real* restrict p,
                                 __global const real* restrict q, __global real* restrict x,
                                 __global real* restrict r, __global real* restrict partial) {
  __local real s[WG];
  real rr = 0;
  for (uint i = get_global_id(0); i < n; i += get_global_size(0)) {
    x[i] += alpha * p[i];
    const real ri = r[i] - alpha * q[i];
    r[i] = ri;
    rr += ri * ri;
  }
  s[get_local_id(0)] = rr;
  group_reduce(s);
  if (get_local_id(0) == 0) partial[get_group_id(0)] = s[0];
}
