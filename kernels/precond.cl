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
  for (uint i = begin; i < end; ++i) {
    const real zi = block_row(i, n, bs, blocks, r);
    z[i] = zi;
    rz += r[i] * zi;
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
