/* Common definitions for every duplexfit program. The host prepends
 *   #define REAL float|double   (and the cl_khr_fp64 pragma for double)
 *   #define WG <work-group size used by the reduction kernels>
 *   #define CHUNK <elements per work-item in the barrier-free chunk kernels>
 *   #define LANES <work-items per row in the row-per-group SpMV>
 * and then concatenates this file with the program's own files (no #include: sources are embedded). */
#ifndef REAL
#error "REAL must be defined by the host (float or double)"
#endif
#ifndef WG
#define WG 256
#endif
#ifndef CHUNK
#define CHUNK 512
#endif
#ifndef LANES
#define LANES 16
#endif

typedef REAL real;

/* Half-open range of elements [*begin, *end) owned by chunk c of CHUNK elements, clipped to n. */
inline void chunk_range(uint c, uint n, uint* begin, uint* end) {
  const ulong b = (ulong)c * (ulong)CHUNK;
  const ulong e = b + (ulong)CHUNK;
  *begin = (uint)min(b, (ulong)n);
  *end = (uint)min(e, (ulong)n);
}

/* Tree reduction of WG values in local memory; the result is in s[0] (all work-items must call it). */
inline void group_reduce(__local real* s) {
  const uint lid = get_local_id(0);
  for (uint stride = WG / 2; stride > 0; stride >>= 1) {
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid < stride) s[lid] += s[lid + stride];
  }
  barrier(CLK_LOCAL_MEM_FENCE);
}
