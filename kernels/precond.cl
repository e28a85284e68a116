/* Preconditioner kernels (needs common.cl).
 * block_jacobi: z = M^-1 r for a block-diagonal M whose blocks are bs consecutive rows of A. blocks holds
 * each block's dense inverse, row-major bs*bs (the last, shorter block is padded). One work-item per row:
 *   z_i = sum_j inv[block(i)][i - base][j] * r[base + j]. */
__kernel void block_jacobi(const uint n, const uint bs, __global const real* restrict blocks,
                           __global const real* restrict r, __global real* restrict z) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  const uint b = i / bs;
  const uint base = b * bs;
  const uint m = min(bs, n - base);
  __global const real* row = blocks + ((ulong)base + (i - base)) * bs;
  real s = 0;
  for (uint j = 0; j < m; ++j) s += row[j] * r[base + j];
  z[i] = s;
}
