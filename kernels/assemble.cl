/* The level system A = Φ + λI on the device (docs/method.md §5, "Assembly on the device"). Program
 * "assemble". One work-item per row i: the centres c_j with ‖c_i − c_j‖ < σ, found on the host's grid of
 * cubic cells of side σ (lib/spatial/cell_grid.hpp: the centres counting-sorted by cell, x fastest, so the
 * cells of one (y, z) row that a query reaches are one run of sorted centres), give the row's entries
 * φ(‖c_i − c_j‖/σ) with Wendland's φ(r) = (1 − r)⁴(4r + 1), and 1 + λ on the diagonal.
 *
 * Its C++ twin is the host assembly (assembleWendland's grid path, lib/field/wendland.cpp, and
 * CellGrid::within): the same cells, the same double arithmetic in the same order (no contraction into
 * fused multiply-adds), the same hit test and the same columns order, so the pattern and the double values
 * are the host's bit for bit; values in REAL are those doubles rounded, as an upload rounds them. Hence the
 * geometry is double whatever REAL is, and the program exists only on devices with cl_khr_fp64 (the host
 * asks for it only there).
 *
 *   n         rows (centres)
 *   q         3 doubles per centre, in row order
 *   xyz, ids  the grid's centres sorted by cell (3 doubles each) and their rows
 *   starts    per cell its first sorted centre, one more entry at the end
 *   geom      lo x, lo y, lo z, 1/cell, radius σ, widened reach, squared-distance bound
 *   dims      cells along x, y, z */
#ifdef cl_khr_fp64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#pragma OPENCL FP_CONTRACT OFF

/* The cell ranges [from, to] along each axis that the query's widened box meets; 0 when it misses. */
inline int assemble_cell_range(const double qx, const double qy, const double qz, __global const double* geom,
                               __global const int* dims, int* from, int* to) {
  const double q[3] = {qx, qy, qz};
  const double reach = geom[5], inv = geom[3];
  for (int a = 0; a < 3; ++a) {
    const double lo = (q[a] - reach - geom[a]) * inv, hi = (q[a] + reach - geom[a]) * inv;
    if (!(hi >= 0.0) || !(lo < (double)dims[a])) return 0;
    from[a] = lo <= 0.0 ? 0 : (int)lo;
    to[a] = hi >= (double)(dims[a] - 1) ? dims[a] - 1 : (int)hi;
  }
  return 1;
}

/* Row i's entries (centres within σ of q, with their rounded distances). With col null they are only
 * counted; else they are also inserted, in ascending column order as they are found (rows have tens of
 * entries), into col and valD from `first` (at most `last`). Returns the count. */
inline uint assemble_row(const double qx, const double qy, const double qz, __global const double* xyz,
                         __global const uint* starts, __global const int* ids, __global const double* geom,
                         __global const int* dims, __global int* col, __global double* valD, const ulong first,
                         const ulong last) {
  const double radius = geom[4], bound = geom[6];
  int from[3], to[3];
  uint hits = 0;
  if (!assemble_cell_range(qx, qy, qz, geom, dims, from, to)) return 0;
  const ulong nx = (ulong)dims[0], ny = (ulong)dims[1];
  for (int iz = from[2]; iz <= to[2]; ++iz) {
    for (int iy = from[1]; iy <= to[1]; ++iy) {
      const ulong row = ((ulong)iz * ny + (ulong)iy) * nx;
      const uint b = starts[row + (ulong)from[0]], e = starts[row + (ulong)to[0] + 1];
      for (uint k = b; k < e; ++k) {
        const double dx = qx - xyz[3 * (ulong)k], dy = qy - xyz[3 * (ulong)k + 1], dz = qz - xyz[3 * (ulong)k + 2];
        const double squared = dx * dx + dy * dy + dz * dz;
        if (!(squared < bound)) continue;
        const double d = sqrt(squared);
        if (!(d < radius)) continue;
        if (col) {
          const ulong out = first + hits;
          if (out >= last) return hits;
          const int c = ids[k];
          ulong j = out;
          for (; j > first && c < col[j - 1]; --j) {
            col[j] = col[j - 1];
            valD[j] = valD[j - 1];
          }
          col[j] = c;
          valD[j] = d;
        }
        ++hits;
      }
    }
  }
  return hits;
}

/* Pass 1: the number of entries of each row. */
__kernel void assemble_count(const uint n, __global const double* q, __global const double* xyz,
                             __global const uint* starts, __global const int* ids, __global const double* geom,
                             __global const int* dims, __global uint* count) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  count[i] = assemble_row(q[3 * (ulong)i], q[3 * (ulong)i + 1], q[3 * (ulong)i + 2], xyz, starts, ids, geom, dims,
                          (__global int*)0, (__global double*)0, 0, 0);
}

/* Pass 2: row i's columns (ascending) and values from rowPtr[i]: the distances sorted with their columns,
 * then φ(d/σ) in place, 1 + λ on the diagonal. With writeReal, the values are also written rounded to REAL
 * into val (float systems). */
__kernel void assemble_fill(const uint n, __global const double* q, __global const double* xyz,
                            __global const uint* starts, __global const int* ids, __global const double* geom,
                            __global const int* dims, __global const int* rowPtr, const double sigma,
                            const double diagonal, const uint writeReal, __global int* col,
                            __global double* valD, __global real* val) {
  const uint i = get_global_id(0);
  if (i >= n) return;
  const ulong first = (ulong)(uint)rowPtr[i], last = (ulong)(uint)rowPtr[i + 1];
  assemble_row(q[3 * (ulong)i], q[3 * (ulong)i + 1], q[3 * (ulong)i + 2], xyz, starts, ids, geom, dims, col, valD,
               first, last);
  for (ulong e = first; e < last; ++e) {
    double v = diagonal;
    if (col[e] != (int)i) {
      const double r = valD[e] / sigma;
      const double s = 1.0 - r;
      const double s2 = s * s;
      v = r >= 1.0 ? 0.0 : s2 * s2 * (4.0 * r + 1.0);
    }
    valD[e] = v;
    if (writeReal) val[e] = (real)v;
  }
}

#endif
