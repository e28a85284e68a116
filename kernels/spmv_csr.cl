/* CSR sparse matrix-vector products y = A*x (rows, row_ptr[rows+1], col[nnz], val[nnz]).
 *  - spmv_csr_row: one row per work-item; the fastest layout on CPU devices (docs/pocl-notes.md).
 *  - spmv_csr_group: LANES consecutive work-items share a row (WG/LANES rows per work-group); each lane
 *    strides over the row, then the lanes reduce in local memory. Coalesced reads for GPUs.
 *    Launch with local size WG exactly and global size = ceil(rows / (WG/LANES)) * WG.
 *  - spmv_csr_row_dot_chunk: work-item c computes rows [c*CHUNK, (c+1)*CHUNK) and also writes
 *    partial[c] = sum of x_i*y_i over them (the fused q = A p, p.q step of CG on CPU devices). */

inline real csr_row_dot(const uint row, __global const uint* restrict row_ptr,
                        __global const uint* restrict col, __global const real* restrict val,
                        __global const real* restrict x) {
  const uint b = row_ptr[row];
  const uint e = row_ptr[row + 1];
  /* Four independent partial sums: without them the row is one serial chain of dependent
   * multiply-adds, bound by the FMA latency rather than by memory on CPU devices (docs/benchmarks.md). */
  real s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  uint k = b;
  for (; k + 4 <= e; k += 4) {
    s0 += val[k] * x[col[k]];
    s1 += val[k + 1] * x[col[k + 1]];
    s2 += val[k + 2] * x[col[k + 2]];
    s3 += val[k + 3] * x[col[k + 3]];
  }
  for (; k < e; ++k) s0 += val[k] * x[col[k]];
  return (s0 + s1) + (s2 + s3);
}

__kernel void spmv_csr_row(const uint rows, __global const uint* restrict row_ptr,
                           __global const uint* restrict col, __global const real* restrict val,
                           __global const real* restrict x, __global real* restrict y) {
  const uint row = get_global_id(0);
  if (row < rows) y[row] = csr_row_dot(row, row_ptr, col, val, x);
}

__kernel void spmv_csr_group(const uint rows, __global const uint* restrict row_ptr,
                             __global const uint* restrict col, __global const real* restrict val,
                             __global const real* restrict x, __global real* restrict y) {
  __local real s[WG];
  const uint lid = get_local_id(0);
  const uint lane = lid % LANES;
  const uint row = get_group_id(0) * (WG / LANES) + lid / LANES;
  real acc = 0;
  if (row < rows) {
    const uint b = row_ptr[row];
    const uint e = row_ptr[row + 1];
    for (uint k = b + lane; k < e; k += LANES) acc += val[k] * x[col[k]];
  }
  s[lid] = acc;
  for (uint stride = LANES / 2; stride > 0; stride >>= 1) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lane < stride) s[lid] += s[lid + stride];
  }
  if (lane == 0 && row < rows) y[row] = s[lid];
}

__kernel void spmv_csr_row_dot_chunk(const uint rows, __global const uint* restrict row_ptr,
                                     __global const uint* restrict col,
                                     __global const real* restrict val,
                                     __global const real* restrict x, __global real* restrict y,
                                     __global real* restrict partial) {
  const uint c = get_global_id(0);
  if ((ulong)c * CHUNK >= rows) return;
  uint begin, end;
  chunk_range(c, rows, &begin, &end);
  real d = 0;
  for (uint row = begin; row < end; ++row) {
    const real v = csr_row_dot(row, row_ptr, col, val, x);
    y[row] = v;
    d += x[row] * v;
  }
  partial[c] = d;
}
