// The OpenMP team queries (private to the library), with their single-thread answers in a build without
// OpenMP: one spelling of the #ifdef for every parallel region that needs its thread's number.
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

namespace duplexfit::detail {

/// omp_get_max_threads(): the size of the next parallel region's team.
inline int maxThreads() noexcept {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

/// omp_get_num_threads(): the current team's size (1 outside a parallel region).
inline int teamSize() noexcept {
#ifdef _OPENMP
  return omp_get_num_threads();
#else
  return 1;
#endif
}

/// omp_get_thread_num(): this thread's number in its team (0 outside a parallel region).
inline int threadId() noexcept {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

}  // namespace duplexfit::detail
