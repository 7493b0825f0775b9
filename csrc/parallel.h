// OpenMP's thread queries, with their one-thread values in a build without OpenMP (where the
// `#pragma omp` lines are ignored and every loop runs serially).
#pragma once

#ifdef _OPENMP
#include <omp.h>
#endif

namespace edgedog {

// Threads a parallel region started now would have.
inline int max_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

// This thread's index inside its parallel region, in [0, max_threads()).
inline int thread_index() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

}  // namespace edgedog
