#include "build_info.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace edgedog {

BuildInfo build_info() {
  BuildInfo info;
#ifdef _OPENMP
  info.openmp = true;
  info.max_threads = omp_get_max_threads();
#else
  info.openmp = false;
  info.max_threads = 1;
#endif
#if defined(__clang__)
  info.compiler = std::string("clang ") + __clang_version__;
#elif defined(__GNUC__)
  info.compiler = std::string("gcc ") + __VERSION__;
#else
  info.compiler = "unknown";
#endif
  return info;
}

}  // namespace edgedog
