/* Preconditioner kernels (needs common.cl).
 * block_jacobi: z = M^-1 r for a block-diagonal M whose blocks are bs consecutive rows of A. blocks holds
 * each block's dense inverse, row-major bs*bs (the last, shorter block is padded). One work-item per row:
 *   z_i = sum_j inv[block(i)][i - base][j] * r[base + j]. */
inline real block_row(const uint i, const uint n, const uint bs, __global const real* restrict blocks,
                      __global const real* restrict r) {
  const uint base = (i / bs) * bs;
  const uint m = min(bs, n - base);
  __global const real* row = blocks + (ulong)i * bs;
  real s = 0;
  for (uint j = 0; j < m; ++j) s += row[j] * r[base + j];
  return s;
}

__kernel void block_jacobi(const uint n, const uint bs, __global const real* restrict blocks,
                           __global const real* restrict r, __global real* restrict z) {
  const uint i = get_global_id(0);
  if (i < n) z[i] = block_row(i, n, bs, blocks, r);
}

/* block_jacobi fused with the reduction r.z: chunk variant (CPU, barrier-free; work-item c owns rows
 * [c*CHUNK, (c+1)*CHUNK)) and group variant (GPU; local size WG exactly). */
__kernel void block_jacobi_dot_chunk(const uint n, const uint bs, __global const real* restrict blocks,
                                     __global const real* restrict r, __global real* restrict z,
                                     __global real* restrict partial) {
  const uint c = get_global_id(0);
  if ((ulong)c * CHUNK >= n) return;
  uint begin, end;
  chunk_range(c, n, &begin, &end);
  real rz = 0;
  for (uint i = begin; i < end;) {
#ifndef REAL_IS_DOUBLE
    if (bs == 16u && i % 16u == 0u && i + 16u <= end) {
      /* A whole 16-row block as z = sum_j M[j][:] r_j, two 8-wide columns a step (M is symmetric, so its
       * row j is its column j): a row's scalar loop of 16 dependent multiply-adds was the kernel's cost,
       * not its bytes. The same products added in the same order per row as block_row. */
      __global const real* m = blocks + (ulong)i * 16u;
      float8 lo = 0, hi = 0;
      for (uint j = 0; j < 16u; ++j) {
        const float rj = r[i + j];
        lo += vload8(0, m + 16u * j) * rj;
        hi += vload8(1, m + 16u * j) * rj;
      }
      vstore8(lo, 0, z + i);
      vstore8(hi, 0, z + i + 8u);
      const float8 p = vload8(0, r + i) * lo + vload8(0, r + i + 8u) * hi;
      const float4 q = p.lo + p.hi;
      rz += (q.s0 + q.s2) + (q.s1 + q.s3);
      i += 16u;
      continue;
    }
#endif
    const real zi = block_row(i, n, bs, blocks, r);
    z[i] = zi;
    rz += r[i] * zi;
    ++i;
  }
  partial[c] = rz;
}

__kernel void block_jacobi_dot_group(const uint n, const uint bs, __global const real* restrict blocks,
                                     __global const real* restrict r, __global real* restrict z,
                                     __global real* restrict partial) {
  __local real s[WG];
  real rz = 0;
  for (uint i = get_global_id(0); i < n; i += get_global_size(0)) {
    const real zi = block_row(i, n, bs, blocks, r);
    z[i] = zi;
    rz += r[i] * zi;
  }
  s[get_local_id(0)] = rz;
  group_reduce(s);
  if (get_local_id(0) == 0) partial[get_group_id(0)] = s[0];
}
